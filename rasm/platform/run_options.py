"""What a run is asked to be, checked before anything is built: its clock, its role, its
transport, a replay (:class:`RunOptions`), and that they fit the app (:func:`check_run`). A bad
combination is refused here, with what to do instead."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any

from rasm.errors import PlatformError, SourceErrors
from rasm.platform.app_charts import check_charts
from rasm.platform.loading import check_components
from rasm.platform.manifest import AppManifest, load_manifest
from rasm.platform.signals import check_app, transport_problems

__all__ = ["Clock", "Role", "RunOptions", "check_run", "check_simulated_run"]


class Clock(StrEnum):
    """The clock a run keeps time by."""

    SIMULATED = "simulated"  # time jumps from job to job: deterministic, as fast as it goes
    WALL = "wall"  # time passes as it does on the wall


class Role(StrEnum):
    """Which side of the application this process runs."""

    ALL = "all"  # both, in one process
    MANAGING = "managing"  # Core, the blocks and the loop; the managed system is elsewhere
    MANAGED = "managed"  # the app's simulator alone, with its probes and effectors

    @property
    def manages(self) -> bool:
        """Whether this process runs the managing side (the blocks and the loop)."""
        return self is not Role.MANAGED

    @property
    def runs_managed_system(self) -> bool:
        """Whether this process runs the managed side (the app's simulator)."""
        return self is not Role.MANAGING


def _member(kind: type[StrEnum], value: object, what: str) -> Any:
    try:
        return kind(value)
    except ValueError:
        known = " or ".join(", ".join(member.value for member in kind).rsplit(", ", 1))
        raise PlatformError(f"unknown {what} {value!r} ({known})") from None


@dataclass(frozen=True)
class RunOptions:
    """How one run goes, besides the app: given whole to :class:`~rasm.Platform`, checked when
    made (a clock or role may be given by name; a replay fixes its clock and transport)."""

    clock: Clock | None = None  # None: the app's (manifest ``clock``), else the wall clock
    seed: int = 0
    transport: str | None = None  # None: the app's, else the in-process bus
    role: Role = Role.ALL
    trace: str | Path | None = None  # a JSONL or MCAP file, or "-" for standard output
    trace_max_bytes: int | None = None  # rotate the trace file at this size
    trace_keep: int = 4  # rotated trace files kept
    knowledge: str | None = None  # the knowledge store's URL; None: the app's
    state_dir: str | Path | None = None  # None: the app's own (rasm.platform.state_dir)
    scenario: dict[str, Any] | None = None  # None: the app's disturbance schedule
    components: dict[str, object] | None = None  # stage (or "twin") -> an object serving it
    # None: stages run on a worker thread on the wall clock (an overrun is walked away from),
    # inline on the simulated clock (deterministic)
    isolate_stages: bool | None = None
    # the process is the loop's own: the objects built before the run are frozen out of the
    # garbage collector's reach (docs/runtime.md)
    low_latency: bool = False
    # refuse an app whose properties or rules read a name no part of it provides
    check_signals: bool = True
    replay: str | Path | None = None  # a rosbag2 recording that drives the loop instead

    def __post_init__(self) -> None:
        set_ = object.__setattr__  # frozen: the checked values replace the given ones
        set_(self, "role", _member(Role, self.role, "role"))
        if self.clock is not None:
            set_(self, "clock", _member(Clock, self.clock, "clock"))
        if self.replay is not None:
            # the recording is the managed system: nothing else runs, nothing is sent, and the
            # loop runs on the recording's own time
            if (self.role is not Role.ALL or self.transport not in (None, "local")
                    or self.clock is Clock.WALL):
                raise PlatformError(
                    "a replay drives the loop from the recording alone: it takes no role, "
                    "no transport and no wall clock"
                )
            set_(self, "clock", Clock.SIMULATED)
            set_(self, "transport", "local")
        if self.components is not None:
            check_components(self.components)
        if self.seed is None:  # an unseeded run (rasm run without --seed) is seed 0
            set_(self, "seed", 0)

    def scenario_of(self, manifest: AppManifest) -> dict[str, Any]:
        """The simulator's disturbance schedule: the one given, else the app's."""
        return manifest.scenario if self.scenario is None else self.scenario


def check_run(
    manifest: AppManifest | str | Path, options: RunOptions
) -> tuple[AppManifest, Clock, str | None]:
    """The app's manifest, the run's clock and its transport URL (None: the in-process bus),
    once the options are known to fit the app.

    Raises :class:`~rasm.errors.PlatformError` for options that do not, and
    :class:`~rasm.errors.SourceErrors` for an app whose properties or rules read a name no part
    of it provides (unless ``options.check_signals`` is false) or whose charts break their
    interface.
    """
    if isinstance(manifest, str | Path):
        manifest = load_manifest(manifest)
    elif not isinstance(manifest, AppManifest):
        raise TypeError(
            f"Platform() takes an app folder, its app.yaml or an AppManifest "
            f"(rasm.platform.load_manifest), not {type(manifest).__name__}"
        )
    role, transport = options.role, options.transport
    if options.check_signals and role.manages:
        # a property or rule reading a name nothing provides: refused before anything runs
        check_app(manifest, transport or manifest.transport)
    elif role.manages:
        # the app's charts are checked even when its signals are not: a replacement chart that
        # lacks a stage state would run nothing, silently
        check_charts(manifest)
        problems = transport_problems(manifest, transport or manifest.transport)
        if problems:
            raise SourceErrors(problems)
    clock = options.clock or _member(Clock, manifest.clock or Clock.WALL, "clock")
    transport = transport or manifest.transport
    if clock is Clock.SIMULATED:
        check_simulated_run(transport, role, bool(manifest.simulator))
    if options.replay is None and role.manages:
        _check_calls(manifest, transport, clock)
    return manifest, clock, transport


def _check_calls(manifest: AppManifest, transport: str, clock: Clock) -> None:
    """A service or action effector calls over ROS 2, on the wall clock: a call's answer
    comes in its own time, which a simulated clock would run past."""
    calls = [e for e in manifest.effectors.values() if e.call]
    if not calls:
        return
    first = calls[0]
    what = f"effector {first.name} calls {first.call} {first.topic}"
    if not transport.strip().startswith(("zenoh://", "dds://")):
        raise PlatformError(
            f"{what}: services and actions are ROS 2's; run the app over zenoh:// or dds:// "
            f"(transport: in app.yaml, or --transport), not {transport}"
        )
    if clock is Clock.SIMULATED:
        raise PlatformError(
            f"{what}: a call is answered in the robot's own time, which the simulated clock "
            "would run past; run it on the wall clock (--clock wall), or --replay a recording"
        )


def check_simulated_run(transport_url: str, role: Role, has_simulator: bool) -> None:
    """Refuse a simulated run whose managed system is in another process on the network:
    nothing could tell when its readings are all in, and the clock would run ahead of them."""
    if transport_url.strip() == "local":
        return
    if role is not Role.ALL:
        where = f"the managed system (--role {role})" if role is Role.MANAGING else (
            "the managing system (--role managed)"
        )
        raise PlatformError(
            f"--clock simulated over {transport_url} needs the managing and the managed system "
            f"in one process, but {where} runs elsewhere: the simulated clock cannot wait for "
            "another process's messages; run a split system on the wall clock (--clock wall)"
        )
    if not has_simulator:
        raise PlatformError(
            f"--clock simulated over {transport_url} needs the app's own simulator "
            "(managed_system.simulator in app.yaml): this app's managed system is another "
            "process, and the simulated clock cannot wait for its messages; run it on the wall "
            "clock (--clock wall)"
        )
