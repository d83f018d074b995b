"""``rasm check PROPS RECORDING...``: many recordings, each reported and a total; a large trace
cut into parts gives the report of one pass; bad recordings are named while the others are
checked; a local worker killed mid-run is replaced and its task done again."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from .conftest import RASM, children, cpu_seconds, rasm
from .traces import write_trace


@pytest.fixture
def traces(tmp_path: Path) -> list[Path]:
    return [write_trace(tmp_path / f"robot{k}.jsonl", 3_000 + 500 * k, seed=k) for k in range(3)]


def one_pass(props: Path, trace: Path, *extra: str) -> subprocess.CompletedProcess:
    return rasm("check", str(props), str(trace), "--jobs", "1", *extra)


def test_many_recordings_give_each_report_in_order_and_a_total(props, traces):
    done = rasm("check", str(props), *map(str, traces), "--format", "json")
    assert done.returncode == 1, done.stderr
    out = json.loads(done.stdout)
    assert [r["recording"] for r in out["recordings"]] == [str(t) for t in traces]
    for entry, trace in zip(out["recordings"], traces, strict=True):
        alone = json.loads(one_pass(props, trace, "--format", "json").stdout)
        assert {k: v for k, v in entry.items() if k != "recording"} == alone
    assert out["total"] == {"recordings": 3, "records": sum(r["records"] for r in
                                                            out["recordings"]),
                            "passed": 0, "failed": 3, "not_checked": 0}


def test_the_text_report_of_many_is_each_recording_s_and_a_total_line(props, traces):
    done = rasm("check", str(props), *map(str, traces))
    expected = "".join(one_pass(props, t).stdout for t in traces)
    records = sum(json.loads(one_pass(props, t, "--format", "json").stdout)["records"]
                  for t in traces)
    assert done.stdout == expected + f"3 recordings, {records} records: 3 fail, 0 pass\n"
    assert done.returncode == 1


def test_bad_recordings_are_named_while_the_others_are_checked(props, traces, tmp_path):
    broken = tmp_path / "broken.jsonl"
    broken.write_text('{"time": 0, "velocity": 0.1}\nnot json\n{"time": 1, "velocity": "x"}\n',
                      encoding="utf-8")
    missing = tmp_path / "missing.jsonl"
    bag = tmp_path / "bag.db3"
    bag.write_bytes(b"SQLite format 3\x00" + bytes(100))
    paths = [traces[0], broken, missing, traces[1], bag]
    done = rasm("check", str(props), *map(str, paths), "--format", "json")
    assert done.returncode == 2
    out = json.loads(done.stdout)
    entries = {e["recording"]: e for e in out["recordings"]}
    assert [e["recording"] for e in out["recordings"]] == [str(p) for p in paths]
    for bad in (broken, missing, bag):
        alone = one_pass(props, bad, "--format", "json")
        assert alone.returncode == 2
        # the same messages as the recording checked alone, each naming it
        assert entries[str(bad)]["error"] == [line.removeprefix("rasm: ")
                                             for line in alone.stderr.splitlines()]
        assert all(str(bad) in line for line in alone.stderr.splitlines()[:1])
        assert alone.stderr in done.stderr
    for good in (traces[0], traces[1]):
        alone = json.loads(one_pass(props, good, "--format", "json").stdout)
        assert {k: v for k, v in entries[str(good)].items() if k != "recording"} == alone
    assert out["total"]["not_checked"] == 3 and out["total"]["failed"] == 2


@pytest.fixture
def large(tmp_path: Path) -> Path:
    return write_trace(tmp_path / "large.jsonl", 120_000, seed=7)


@pytest.mark.parametrize("form", ["json", "text"])
def test_a_large_trace_in_parts_gives_the_report_of_one_pass(props, large, form):
    whole = one_pass(props, large, "--format", form)
    parts = rasm("check", str(props), str(large), "--jobs", "2", "--part-size", "300k",
                 "--format", form)
    assert parts.returncode == whole.returncode == 1
    assert parts.stdout == whole.stdout
    assert parts.stderr == whole.stderr == ""


def test_a_malformed_record_in_a_part_is_reported_as_one_pass_reports_it(props, tmp_path):
    trace = write_trace(tmp_path / "t.jsonl", 60_000)
    lines = trace.read_text(encoding="utf-8").splitlines(keepends=True)
    lines[40_000] = '{"time": 400, "velocity": "fast"}\n'
    trace.write_text("".join(lines), encoding="utf-8")
    whole = one_pass(props, trace)
    parts = rasm("check", str(props), str(trace), "--jobs", "2", "--part-size", "200k")
    assert whole.returncode == parts.returncode == 2
    assert parts.stderr == whole.stderr and ":40001:" in whole.stderr
    assert parts.stdout == whole.stdout == ""


def test_bad_usage_is_refused(props, traces):
    for args, words in [(["--jobs", "0"], "--jobs must be 1 or more"),
                        (["--verdicts"], "--verdicts prints every verdict of one recording"),
                        (["--cluster", "tcp://127.0.0.1:1", "--jobs", "2"], "--jobs sets")]:
        done = rasm("check", str(props), *map(str, traces), *args)
        assert done.returncode == 2 and words in done.stderr and "Traceback" not in done.stderr


def test_cluster_without_dask_names_the_extra(props, traces):
    # the engine made unimportable, as in an install without the 'cluster' extra
    code = ("import sys; sys.modules['distributed'] = None; from rasm.cli import main; "
            f"sys.exit(main(['check', {str(props)!r}, {str(traces[0])!r}, '--cluster', "
            "'tcp://127.0.0.1:1']))")
    done = subprocess.run([RASM[0], "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert "pip install 'rasm[cluster]'" in done.stderr and "Traceback" not in done.stderr


def test_a_worker_killed_mid_run_is_replaced_and_the_report_is_that_of_one_pass(props,
                                                                             tmp_path):
    trace = write_trace(tmp_path / "t.jsonl", 400_000, seed=3)
    whole = one_pass(props, trace, "--format", "json")
    check = subprocess.Popen([*RASM, "check", str(props), str(trace), "--jobs", "2",
                              "--part-size", "2M", "--format", "json"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed = None
    deadline = time.monotonic() + 120
    while killed is None and time.monotonic() < deadline and check.poll() is None:
        for pid in children(check.pid):
            try:
                command = Path(f"/proc/{pid}/cmdline").read_bytes()
            except OSError:
                continue
            # a pool worker well into a task (not the resource tracker)
            if b"spawn_main" in command and cpu_seconds(pid) > 0.5:
                os.kill(pid, signal.SIGKILL)
                killed = pid
                break
        else:
            time.sleep(0.05)
    out, err = check.communicate(timeout=600)
    assert killed is not None, "no worker was seen at work"
    assert check.returncode == whole.returncode == 1, err
    assert out == whole.stdout and err == ""


def test_a_long_check_shows_a_progress_bar_on_a_terminal_and_the_same_report(props, large,
                                                                             tmp_path):
    import pty

    whole = one_pass(props, large, "--format", "json")
    terminal, stderr = pty.openpty()
    report = tmp_path / "report.json"
    with open(report, "wb") as stdout:  # (a pipe would fill while the terminal is read)
        check = subprocess.Popen([*RASM, "check", str(props), str(large), "--jobs", "2",
                                  "--part-size", "300k", "--format", "json"],
                                 stdout=stdout, stderr=stderr)
    os.close(stderr)
    shown = b""
    while True:
        try:
            data = os.read(terminal, 65536)
        except OSError:  # the terminal closed with the process
            break
        if not data:
            break
        shown += data
    check.wait(timeout=600)
    os.close(terminal)
    assert check.returncode == 1
    assert report.read_text() == whole.stdout
    assert b"checking" in shown and b"MB" in shown  # the bar, its bytes done and in all
