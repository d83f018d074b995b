"""What a run is asked to be, checked before anything is built: the app, its role, its clock,
its transport, a replay. A bad combination is refused here, with what to do instead."""

from __future__ import annotations

from pathlib import Path

from rasm.errors import PlatformError, SourceErrors
from rasm.platform.app_charts import check_charts
from rasm.platform.loading import check_components
from rasm.platform.manifest import AppManifest, load_manifest
from rasm.platform.signals import check_app, transport_problems
from rasm.platform.simulated_clock import check_simulated_run

__all__ = ["check_run"]

ROLES = ("all", "managing", "managed")


def check_run(
    manifest: AppManifest | str | Path,
    *,
    role: str,
    clock: str | None,
    transport: str | None,
    replay: str | Path | None,
    components: dict[str, object] | None,
    check_signals: bool,
) -> tuple[AppManifest, str, str | None]:
    """The app's manifest, the run's clock (``simulated`` or ``wall``) and its transport URL
    (None: the manifest's or the in-process bus), once the options are known to fit together.

    Raises :class:`~rasm.errors.PlatformError` for options that do not, and
    :class:`~rasm.errors.SourceErrors` for an app whose properties or rules read a name no part
    of it provides (unless ``check_signals`` is false) or whose charts break their interface.
    """
    if role not in ROLES:
        raise PlatformError(f"unknown role {role!r} (all, managing or managed)")
    if replay is not None:
        # the recording is the managed system: nothing else runs, nothing is sent, and the loop
        # runs on the recording's own time
        if role != "all" or transport not in (None, "local") or clock == "wall":
            raise PlatformError(
                "a replay drives the loop from the recording alone: it takes no role, "
                "no transport and no wall clock"
            )
        clock, transport = "simulated", "local"
    if isinstance(manifest, str | Path):
        manifest = load_manifest(manifest)
    elif not isinstance(manifest, AppManifest):
        raise TypeError(
            f"Platform() takes an app folder, its app.yaml or an AppManifest "
            f"(rasm.platform.load_manifest), not {type(manifest).__name__}"
        )
    if check_signals and role != "managed":
        # a property or rule reading a name nothing provides: refused before anything runs
        check_app(manifest, transport or manifest.transport)
    elif role != "managed":
        # the app's charts are checked even when its signals are not: a replacement chart that
        # lacks a stage state would run nothing, silently
        check_charts(manifest)
        problems = transport_problems(manifest, transport or manifest.transport)
        if problems:
            raise SourceErrors(problems)
    if clock not in (None, "simulated", "wall"):
        raise PlatformError(f"unknown clock {clock!r} (simulated or wall)")
    if components is not None:
        check_components(components)
    clock = clock or manifest.clock or "wall"
    transport = transport or manifest.transport
    if clock == "simulated":
        check_simulated_run(transport, role, bool(manifest.simulator))
    if replay is None and role != "managed":
        _check_calls(manifest, transport, clock)
    return manifest, clock, transport


def _check_calls(manifest: AppManifest, transport: str, clock: str) -> None:
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
    if clock == "simulated":
        raise PlatformError(
            f"{what}: a call is answered in the robot's own time, which the simulated clock "
            "would run past; run it on the wall clock (--clock wall), or --replay a recording"
        )
