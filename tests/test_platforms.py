"""Windows and macOS paths, run on this machine by imitating them: pip's gistools.exe launcher (a zip application),
text files whatever the locale's encoding, the run lock without /proc, workers whose parent's id stays (Windows),
workers without a console window, files held open, names that differ in case, and ``=`` in a file's path."""

from __future__ import annotations

import ast
import json
import multiprocessing
import os
import shutil
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from conftest import ROOT, SAMPLE
from gistools.cli.main import cli

GISTOOLS = [sys.executable, "-m", "gistools.cli.main"]


def _text_opens_without_encoding(root: Path) -> list[str]:
    found = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.Call):
                continue
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else None
            if "encoding" in {k.arg for k in node.keywords}:
                continue
            if name in ("write_text", "read_text") and isinstance(f, ast.Attribute):
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {name}()")
            elif (name == "open" and isinstance(f, ast.Name)) or (name == "fdopen" and isinstance(f, ast.Attribute)):
                mode = node.args[1] if len(node.args) > 1 else next((k.value for k in node.keywords if k.arg == "mode"),
                                                                     None)
                text = "r" if mode is None else mode.value if isinstance(mode, ast.Constant) else "?"
                if "b" not in str(text):
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno} {name}({text!r})")
    return found


def test_every_text_file_is_opened_with_its_encoding_named():
    """A text file written without an encoding takes the locale's (cp1252 on most Windows machines): a tile named
    Łódź then breaks the VRT. Every text-mode open, read_text and write_text names it."""
    found = _text_opens_without_encoding(ROOT / "gistools") + _text_opens_without_encoding(ROOT / "qgis_plugin")
    assert not found, "\n".join(found)


def test_tiles_named_in_any_script_make_a_vrt_report_and_style_gdal_reads_whole(tmp_path):
    """Tiles named Łódź, Zürich and 東京 through the shrub chain, every text write checked: a write that would take
    the locale's encoding raises (EncodingWarning made an error for gistools' modules). The VRT opens in GDAL with
    every cell of its tiles, the record and the style read as UTF-8 and name the tiles."""
    tiles = tmp_path / "tiles"
    tiles.mkdir()
    sources = sorted(SAMPLE.glob("*.la[sz]"))
    for src, name in zip(sources, ["Łódź", "Zürich", "東京", "plain"]):
        shutil.copy(src, tiles / f"{name}{src.suffix}")
    out = tmp_path / "out"
    script = ("import sys, warnings; warnings.filterwarnings('error', category=EncodingWarning, "
              "module=r'gistools(\\..*)?$'); from gistools.cli.main import main; sys.argv = ['gistools'] + "
              "sys.argv[1:]; main()")
    done = subprocess.run([sys.executable, "-X", "warn_default_encoding", "-c", script, "shrub", str(tiles), "--out",
                           str(out), "-q"], capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    assert not [line for line in done.stderr.splitlines() if "gistools" in line and "Encoding" in line], done.stderr
    with rasterio.open(out / "dsm.vrt") as vrt:
        mosaic = vrt.read(1, masked=True)
        sources_in_vrt = {Path(f).stem for f in vrt.files[1:]}
    assert {"Łódź", "Zürich", "東京"} <= sources_in_vrt
    valid = 0
    for tif in sorted((out / "dsm").glob("*.tif")):
        with rasterio.open(tif) as src:
            valid += int(src.read(1, masked=True).count())
    assert int(mosaic.count()) == valid > 0  # every cell of every tile, none lost to a mis-decoded name
    record = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert {"Łódź", "Zürich", "東京"} <= {t["name"] for t in record["tiles"]}
    import xml.etree.ElementTree as ET

    ET.fromstring((out / "shrub_classes.qml").read_bytes())  # the style parses


def _launcher(folder: Path) -> Path:
    """pip's console-script launcher as Windows has it: a zip application named gistools.exe whose __main__.py is
    the entry point's script (with its guard)."""
    exe = folder / "gistools.exe"
    with zipfile.ZipFile(exe, "w") as z:
        z.writestr("__main__.py", "import re\nimport sys\nfrom gistools.cli.main import main\n"
                                  "if __name__ == '__main__':\n"
                                  "    sys.argv[0] = re.sub(r'(-script\\.pyw|\\.exe)?$', '', sys.argv[0])\n"
                                  "    sys.exit(main())\n")
    return exe


def test_the_windows_launcher_starts_worker_processes(tmp_path):
    """``gistools.exe --jobs 2`` (the launcher's __main__ lives inside the exe, not on the disk): workers spawn, the
    tiles do not run one at a time, and the rasters equal a one-job run's."""
    exe = _launcher(tmp_path)
    done = subprocess.run([sys.executable, str(exe), "-v", "rasters", str(SAMPLE), "--out", str(tmp_path / "two"),
                           "--jobs", "2", "-q"], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "one at a time" not in done.stderr and "standard input" not in done.stderr, done.stderr
    one = subprocess.run(GISTOOLS + ["rasters", str(SAMPLE), "--out", str(tmp_path / "one"), "--jobs", "1", "-q"],
                         capture_output=True, text=True, timeout=600)
    assert one.returncode == 0, one.stderr
    for tif in sorted((tmp_path / "one" / "dem").glob("*.tif")):
        with rasterio.open(tif) as a, rasterio.open(tmp_path / "two" / "dem" / tif.name) as b:
            assert np.array_equal(a.read(1), b.read(1), equal_nan=True)


def test_a_guard_in_a_comment_or_a_string_is_no_guard(tmp_path):
    from gistools.engine.batch import has_main_guard

    cases = {
        "# if __name__ == '__main__':\nrun()\n": False,
        "text = 'if __name__ == \"__main__\":'\nrun()\n": False,
        "def f():\n    if __name__ == '__main__':\n        run()\n": False,
        "if __name__ == '__main__':\n    run()\n": True,
        "if '__main__' == __name__:\n    run()\n": True,
    }
    for i, (text, guarded) in enumerate(cases.items()):
        script = tmp_path / f"s{i}.py"
        script.write_text(text, encoding="utf-8")
        assert has_main_guard(script) is guarded, text


ORPHAN = """
import multiprocessing, os, sys, time


def orphan(parent_pid, ready):  # a worker whose os.getppid() keeps its dead parent's id, as on Windows
    from gistools.engine import batch

    os.getppid = lambda: parent_pid
    batch._worker_start(parent_pid, False)
    ready.set()
    time.sleep(60)


if __name__ == "__main__":
    ctx = multiprocessing.get_context("spawn")
    ready = ctx.Event()
    child = ctx.Process(target=orphan, args=(os.getpid(), ready))
    child.start()
    ready.wait(60)
    print(child.pid, flush=True)
    os._exit(0)  # the parent dies without stopping its worker
"""


def test_a_worker_ends_when_its_parent_dies_though_the_parents_id_stays(tmp_path):
    script = tmp_path / "parent.py"
    script.write_text(ORPHAN, encoding="utf-8")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip().isdigit(), done.stderr
    worker = int(done.stdout)

    def alive(pid):
        try:
            return Path(f"/proc/{pid}/stat").read_text(encoding="utf-8").rsplit(")", 1)[1].split()[0] != "Z"
        except OSError:
            return False

    deadline = time.monotonic() + 5
    while alive(worker) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not alive(worker), "the orphaned worker still runs 5 s after its parent died"


def test_workers_started_from_qgis_on_windows_run_pythonw(tmp_path, monkeypatch):
    """Inside QGIS sys.executable is qgis-bin.exe; the workers' interpreter is pythonw.exe (no console window)."""
    from gistools.engine import batch

    for name in ("python.exe", "pythonw.exe"):
        (tmp_path / name).write_bytes(b"")
    monkeypatch.setattr(sys, "executable", str(tmp_path / "qgis-bin.exe"))
    monkeypatch.setattr(sys, "exec_prefix", str(tmp_path))
    monkeypatch.setattr(os, "name", "nt")
    assert batch.python_executable() == str(tmp_path / "pythonw.exe")


def test_the_lock_without_proc_or_psutil_tells_a_reused_pid_from_its_run(tmp_path, monkeypatch):
    """macOS: no /proc, no psutil. A lock whose pid now belongs to another process (started at another time) is
    stale and taken over; the lock of the live run that holds it is respected."""
    from gistools.errors import OutputBusyError
    from gistools.io import outdir

    monkeypatch.setattr(outdir, "PROC", tmp_path / "no-proc")
    monkeypatch.setattr(outdir, "_psutil", lambda: None)
    sleeper = subprocess.Popen(["sleep", "60"])
    try:
        out = tmp_path / "out"
        out.mkdir()
        lock = out / outdir.LOCK_NAME
        real = outdir._process_start(sleeper.pid)
        assert real and real.startswith("p")
        import socket

        lock.write_text(json.dumps({"pid": sleeper.pid, "host": socket.gethostname(), "start": "pMon Jan  1 00:00:00 "
                                    "2001", "since": "then"}), encoding="utf-8")  # the pid, reused since
        with outdir.claim_output(out, "gistools test"):
            pass
        lock.write_text(json.dumps({"pid": sleeper.pid, "host": socket.gethostname(), "start": real, "since": "now"}),
                        encoding="utf-8")
        with pytest.raises(OutputBusyError):
            with outdir.claim_output(out, "gistools test"):
                pass
    finally:
        sleeper.kill()
        sleeper.wait()


def test_a_file_held_open_is_replaced_once_released_or_named_in_one_line(tmp_path, monkeypatch):
    """Windows refuses os.replace onto a file another program holds open (PermissionError): the rename is tried
    again, and where the file stays held the error names it and QGIS. Imitated with os.replace refusing."""
    from gistools.io import atomic

    target = tmp_path / "dsm.tif"
    target.write_bytes(b"old")
    calls = {"n": 0}
    real = os.replace

    def held(src, dst):
        calls["n"] += 1
        if calls["n"] <= 2:
            raise PermissionError(13, "The process cannot access the file because it is being used by another process")
        real(src, dst)

    monkeypatch.setattr(atomic.os, "replace", held)
    tmp = tmp_path / "new"
    tmp.write_bytes(b"new")
    atomic.replace(tmp, target, tries=(0.01, 0.01, 0.01), windows=True)
    assert target.read_bytes() == b"new" and calls["n"] == 3
    monkeypatch.setattr(atomic.os, "replace", lambda s, d: (_ for _ in ()).throw(PermissionError(13, "in use")))
    tmp.write_bytes(b"newer")
    with pytest.raises(atomic.HeldOpenError) as err:
        atomic.replace(tmp, target, tries=(0.01,), windows=True)
    assert str(target) in str(err.value) and "QGIS" in str(err.value) and "\n" not in str(err.value)


def test_tiles_whose_names_differ_only_in_case_are_refused(tmp_path):
    for name in ("A", "a"):
        shutil.copy(SAMPLE / "35712.las", tmp_path / f"{name}.las")
    result = CliRunner().invoke(cli, ["rasters", str(tmp_path), "--out", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 1 and "differ only in case" in result.output, result.output


def test_a_contacts_file_whose_path_holds_an_equals_sign_is_read(tmp_path):
    """``gistools aquifer model run=1/contacts.csv ...``: a file, not the dissertation's LAYER=path form."""
    folder = tmp_path / "run=1"
    folder.mkdir()
    done = subprocess.run(GISTOOLS + ["examples", str(tmp_path / "ex")], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    shutil.copy(tmp_path / "ex" / "contacts.csv", folder / "contacts.csv")
    run = subprocess.run(GISTOOLS + ["aquifer", "model", "run=1/contacts.csv", "--layers", "LS,AU,AD,AQ", "--crs",
                                     "EPSG:3003", "--out", "milan"], cwd=tmp_path, capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "milan" / "report.json").is_file()
