"""The scanatlas Python package: the four calls, their options, errors and progress."""

import threading
import time
from pathlib import Path

import pytest

import scanatlas
from conftest import write_grid_scan


def test_plugins_lists_every_kind_with_parameters():
    plugins = scanatlas.plugins()
    assert isinstance(plugins, list)
    names = {(p["kind"], p["name"]) for p in plugins}
    assert ("scorer", "paper") in names
    assert ("solver", "slim") in names and ("solver", "arap") in names
    assert ("packer", "horizon") in names
    slim = next(p for p in plugins if p["name"] == "slim")
    assert any(param["name"] == "max-iterations" for param in slim["params"])


def test_stats_of_the_fragmented_scan(scan: Path):
    figures = scanatlas.stats(scan)
    assert figures["faces"] == 72
    assert figures["charts_edge"] == 36
    assert figures["texture_sheets"] == 1


def test_defrag_merges_charts_and_writes_the_output(scan: Path, tmp_path: Path):
    out = tmp_path / "out" / "scan.obj"
    out.parent.mkdir()
    report = scanatlas.defrag(scan, out, matching_tolerance=2, solver="arap+slim")
    merge = report["merge"]
    assert merge["charts_before"] == 36
    assert merge["charts_after"] < merge["charts_before"]
    assert merge["accepted"] > 0
    assert out.exists()
    after = scanatlas.stats(out)
    assert after["faces"] == 72
    assert after["charts_edge"] == merge["charts_after"]


def test_texture_size_options_fix_every_sheet(scan: Path, tmp_path: Path):
    out = tmp_path / "fixed" / "scan.obj"
    report = scanatlas.defrag(scan, out, sheet_size=256, pow2=True)
    sizes = [(s["width"], s["height"]) for s in scanatlas.stats(out)["texture_sizes"]]
    assert sizes and all(s == (256, 256) for s in sizes), sizes
    assert report["pack_options"]["sheet_size"] == [256, 256]


def test_same_options_give_the_same_bytes(scan: Path, tmp_path: Path):
    outputs = []
    for k in range(2):
        out = tmp_path / f"run{k}" / "scan.obj"
        out.parent.mkdir()
        scanatlas.defrag(str(scan), str(out), packer="skyline", padding=2, no_retry=True)
        outputs.append(out.read_bytes())
    assert outputs[0] == outputs[1]


def test_progress_callback_sees_every_stage(scan: Path, tmp_path: Path):
    stages = []
    scanatlas.defrag(scan, tmp_path / "o.obj", progress=stages.append)
    assert stages[0] == "loading"
    assert "merging charts" in stages and "writing the model" in stages


def test_a_raising_callback_is_raised_after_the_run(scan: Path, tmp_path: Path):
    def boom(stage):
        raise RuntimeError(f"stop at {stage}")

    with pytest.raises(RuntimeError, match="stop at loading"):
        scanatlas.defrag(scan, tmp_path / "o.obj", progress=boom)


def test_the_gil_is_released_while_working(tmp_path: Path):
    # A larger scan than the shared fixture, so the run lasts long enough for a thread beside it
    # to tick many times whatever the machine's load.
    folder = tmp_path / "big"
    folder.mkdir()
    big = write_grid_scan(folder, n=32, texture_side=512)
    ticks = []
    done = threading.Event()

    def ticker():
        while not done.is_set():
            ticks.append(time.monotonic())
            done.wait(0.001)

    t = threading.Thread(target=ticker)
    t.start()
    try:
        started = time.monotonic()
        scanatlas.defrag(big, tmp_path / "o.obj")
        ended = time.monotonic()
    finally:
        done.set()
        t.join()
    # Only ticks stamped while the call ran count: with the GIL held for the whole call the
    # ticker could not run at all between its start and its end.
    inside = [s for s in ticks if started < s < ended]
    assert len(inside) > 5, (len(inside), ended - started)


@pytest.mark.parametrize(
    "options, needle",
    [
        ({"solver": "slimm"}, "slimm"),
        ({"matching_tolerence": 2}, "matching_tolerence"),
        ({"no_retry": False, "alpah": 3}, "alpah"),
        ({"padding": -1}, "padding"),
        ({"jpeg_quality": 0}, "jpeg-quality"),
        ({"local_distortion": "big"}, "local-distortion"),
        ({"threads": 2}, "threads"),
    ],
)
def test_bad_options_are_value_errors(scan: Path, tmp_path: Path, options, needle):
    with pytest.raises(ValueError, match=needle):
        scanatlas.defrag(scan, tmp_path / "o.obj", **options)
    assert not (tmp_path / "o.obj").exists()


def test_missing_files_are_os_errors(tmp_path: Path):
    with pytest.raises(OSError):
        scanatlas.defrag(tmp_path / "missing.obj", tmp_path / "o.obj")
    with pytest.raises(OSError):
        scanatlas.stats(tmp_path / "missing.glb")


def test_bad_models_are_model_errors(tmp_path: Path):
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    with pytest.raises(scanatlas.ModelError, match="bad.obj"):
        scanatlas.defrag(bad, tmp_path / "o.obj")
    assert issubclass(scanatlas.ModelError, Exception)
    assert not issubclass(scanatlas.ModelError, (ValueError, OSError))


def test_the_input_is_never_overwritten(scan: Path):
    before = scan.read_bytes()
    with pytest.raises(ValueError, match="is the input"):
        scanatlas.defrag(scan, scan)
    assert scan.read_bytes() == before


def test_build_refuses_bad_options_and_missing_cameras(scan: Path, tmp_path: Path):
    with pytest.raises(ValueError, match="no_such"):
        scanatlas.build(scan, tmp_path, tmp_path, tmp_path / "o.obj", no_such=1)
    # A cameras path that holds no camera model is a bad input, not a bad option.
    with pytest.raises(scanatlas.ModelError, match="not a COLMAP model folder"):
        scanatlas.build(scan, tmp_path / "none", tmp_path, tmp_path / "o.obj")


def test_report_option_writes_the_same_report(scan: Path, tmp_path: Path):
    import json

    path = tmp_path / "report.json"
    report = scanatlas.defrag(scan, tmp_path / "o.obj", report=path)
    assert json.loads(path.read_text())["merge"] == report["merge"]
