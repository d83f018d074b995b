"""``rasm report`` on the command line: a page for any trace, exit 2 with the place on bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rasm.cli import main


def _report(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    code = main(["report", *args])
    return code, capsys.readouterr().err


def test_a_hotbox_trace_gives_a_page(hotbox_trace: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "r.html"
    code, err = _report(capsys, str(hotbox_trace), "-o", str(out))
    assert code == 0
    assert f"{out}: " in err and "3 adaptations" in err
    html = out.read_text(encoding="utf-8")
    assert html.startswith("<!DOCTYPE html>") and "Plotly" in html


def test_not_a_trace_names_file_and_line(tmp_path: Path, capsys) -> None:
    trace = tmp_path / "notes.txt"
    trace.write_text("# a shopping list\nbread\n")
    out = tmp_path / "r.html"
    code, err = _report(capsys, str(trace), "-o", str(out))
    assert code == 2
    assert f"{trace}:1:1: not valid JSON" in err and f"{trace}:2:1: not valid JSON" in err
    assert not out.exists()


def test_an_empty_trace_says_so(tmp_path: Path, capsys) -> None:
    trace = tmp_path / "empty.jsonl"
    trace.write_text("\n\n")
    code, err = _report(capsys, str(trace), "-o", str(tmp_path / "r.html"))
    assert code == 2
    assert f"{trace}:1: empty trace: no records" in err


@pytest.mark.parametrize(
    ("lines", "where", "message"),
    [
        (['{"time": 0, "x": 1}', "[1, 2]"], ":2:1:", "must be a JSON object"),
        (['{"time": 0}', '{"x": 1}'], ":2:1:", "without 'time'"),
        (['{"time": 2}', '{"time": 1}'], ":2:2:", "goes back in time"),
        (['{"time": 0, "stage": "monitor", "duration": "slow"}'], ":1:", "'duration' must be"),
    ],
)
def test_bad_records_are_placed(tmp_path: Path, capsys, lines, where, message) -> None:
    trace = tmp_path / "bad.jsonl"
    trace.write_text("\n".join(lines) + "\n")
    code, err = _report(capsys, str(trace), "-o", str(tmp_path / "r.html"))
    assert code == 2
    assert f"{trace}{where}" in err and message in err
    assert "Traceback" not in err


def test_a_missing_file_or_a_folder(tmp_path: Path, capsys) -> None:
    code, err = _report(capsys, str(tmp_path / "nope.jsonl"), "-o", str(tmp_path / "r.html"))
    assert code == 2 and "nope.jsonl" in err
    code, err = _report(capsys, str(tmp_path), "-o", str(tmp_path / "r.html"))
    assert code == 2 and f"{tmp_path}: is a folder" in err


def test_a_bad_property_file_is_placed(tmp_path: Path) -> None:
    from rasm.errors import SourceError, SourceErrors
    from rasm.report import write_report

    trace = tmp_path / "t.jsonl"
    trace.write_text(json.dumps({"time": 0, "x": 1}) + "\n")
    props = tmp_path / "p.rv"
    props.write_text("property broken:\n    always (x <=)\n")
    with pytest.raises((SourceError, SourceErrors), match=r"p\.rv:2"):
        write_report(trace, tmp_path / "r.html", [props])


def test_the_missing_parts_are_named(tmp_path: Path, capsys) -> None:
    trace = tmp_path / "plain.jsonl"
    trace.write_text(json.dumps({"time": 0, "velocity": 0.1}) + "\n")
    code, err = _report(capsys, str(trace), "-o", str(tmp_path / "r.html"))
    assert code == 0
    assert "note: no MAPLE-K stage timing" in err and "note: no adaptations" in err
    assert "property stage_order not judged: no value for stage in this trace" in err


def test_a_trace_that_is_not_utf8_is_placed_at_its_first_bad_byte(tmp_path: Path, capsys) -> None:
    trace = tmp_path / "t.jsonl"
    trace.write_bytes(b'{"time": 0, "stage": "monitor", "duration": 0.1}\n{"time": 1, \xff}\n')
    assert main(["report", str(trace), "-o", str(tmp_path / "r.html")]) == 2
    assert f"{trace}:2:13: not a UTF-8 text file" in capsys.readouterr().err


def test_the_app_sets_the_platform_properties_and_brings_its_own(hotbox_trace: Path,
                                                                  tmp_path: Path, capsys) -> None:
    import shutil

    from rasm.report import build_model

    from .conftest import HOTBOX

    app = tmp_path / "hotbox"
    shutil.copytree(HOTBOX, app, ignore=shutil.ignore_patterns(".rasm", "__pycache__"))
    manifest = app / "app.yaml"
    manifest.write_text(manifest.read_text() + "platform_properties:\n  no_oscillation: off\n"
                        "  stage_budget: {max_duration: 0.000001}\n")
    model = build_model(hotbox_trace, app=app)
    verdicts = {t["name"]: t["verdict"] for t in model["properties"]["timelines"]}
    assert "no_oscillation" not in verdicts and model["properties"]["off"] == ["no_oscillation"]
    assert verdicts["stage_budget"] == "violated"  # no stage takes under a microsecond
    assert verdicts["temperature_band"] == "satisfied"  # the app's own files, without --props
    assert model["properties"]["files"][:2] == ["rasm:properties/adaptation.rv",
                                                "rasm:properties/maple_k.rv"]
    code, err = _report(capsys, str(hotbox_trace), "-o", str(tmp_path / "r.html"), "--app",
                        str(app))
    assert code == 0
    assert "rasm: note: platform properties off for this app (not checked): no_oscillation" in err
