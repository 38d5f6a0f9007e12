"""Integrity (issue 24): nothing forged, nothing lost.

* **Output directories** — ``simulate``, ``reproduce`` and ``study`` replace (or, for a study,
  write into) an existing ``--out`` only if this toolkit wrote it: it holds the marker file
  :data:`ilc_analysis._output.OUTPUT_MARKER` (the command and the version). A non-empty
  directory without it — whatever its files are called, e.g. the user's own ``summary.json`` —
  is refused with exit 2 naming ``--out``, and left byte for byte as it was.
* **Learner state** — concurrent ``learn`` calls on one ``--state`` are serialised by a
  portable lock (no update is lost), or refused naming ``--state`` when the lock stays held.
* **Studies** — each ``done/`` marker holds the SHA-256 of its chunk's data; a resumed study
  verifies every marker against the data and recomputes (and reports) what fails: forged
  markers over NaN points, swapped, altered or missing chunk files.

Each table case asserts the exit status, the one-line message naming the parameter, and the
file system before and after. Concurrency is tested with subprocesses that meet at a barrier
(no sleeps, no assertion on timing; the timeouts only bound a hang).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from test_study import STUDY, _design

from ilc_analysis import __version__, _output
from ilc_analysis.cli import _learn_command as learn_command
from ilc_analysis.cli import _reproduce_command as reproduce_command
from ilc_analysis.cli.main import main
from ilc_analysis.paper import load_scenario
from ilc_analysis.paper._pipeline import run_paper
from ilc_analysis.simulation import write_input_csv
from ilc_analysis.studies import Compute, Study, grid, load_study, run_study

#: bound of one subprocess [s] (a hang fails the test; nothing is timed)
PROCESS_LIMIT = 300
SHORT_SCENARIO = "horizon = 0.3\niterations = 2\nlead = 2\n"


def _tree(path: Path) -> dict[str, bytes]:
    """Every file under ``path`` (relative name -> bytes); directories as ``name/``."""
    out: dict[str, bytes] = {}
    for p in sorted(path.rglob("*")):
        rel = str(p.relative_to(path))
        if p.is_symlink():
            out[rel] = b"-> " + os.readlink(p).encode()
        elif p.is_dir():
            out[rel + "/"] = b""
        else:
            out[rel] = p.read_bytes()
    return out


def _leftovers(parent: Path) -> list[str]:
    return sorted(p.name for p in parent.iterdir()
                  if ".tmp-" in p.name or ".old-" in p.name or p.name.endswith(".lock"))


# ---------------------------------------------------------------------------------------------
# output directories
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    """A short paper run (30 samples, 2 iterations) for ``reproduce`` to write."""
    path = tmp_path_factory.mktemp("scenario") / "short.toml"
    path.write_text(SHORT_SCENARIO)
    return run_paper(load_scenario(path).replace(disturbance_amplitude=0.0))


@pytest.fixture
def argv_for(tmp_path, monkeypatch, short_run):
    """``argv_for(command, out)``: a fast, valid run of ``command`` into ``out``."""
    design = _design(tmp_path / "design.toml")
    study = tmp_path / "study.toml"
    study.write_text(STUDY.replace("count = 3", "count = 1")
                     .replace("values = [0.85, 0.95]", "values = [0.9]")
                     .replace("values = [0.0, 1e-4]", "values = [0.0]"))
    monkeypatch.setattr(reproduce_command, "run_paper", lambda *a, **k: short_run)

    def argv(command: str, out: Path) -> list[str]:
        return {"simulate": ["simulate", str(design), "--iterations", "2", "--out", str(out)],
                "reproduce": ["reproduce", "--quiet", "--out", str(out)],
                "study": ["study", str(study), "--out", str(out), "--serial",
                          "--no-progress", "--no-figures"]}[command]
    return argv


def _users_summary(out: Path) -> None:
    """The issue's case: a user's own directory holding only their ``summary.json`` (a name
    every one of the three commands writes), no marker."""
    out.mkdir()
    (out / "summary.json").write_text('{"mine": "measured on the real machine"}\n')


def _marker_is_a_directory(out: Path) -> None:
    out.mkdir()
    (out / _output.OUTPUT_MARKER).mkdir()
    (out / "summary.json").write_text('{"mine": 1}\n')


def _marker_is_a_symlink(out: Path) -> None:
    out.mkdir()
    (out.parent / "elsewhere").write_text("not a marker the toolkit wrote")
    (out / _output.OUTPUT_MARKER).symlink_to(out.parent / "elsewhere")
    (out / "summary.json").write_text('{"mine": 1}\n')


def _earlier_run(out: Path) -> None:
    """An output directory this toolkit's ``simulate`` wrote earlier (its marker)."""
    out.mkdir()
    _output.write_output_marker(out, "ilc-analysis simulate")
    (out / "summary.json").write_text('{"run": "previous"}\n')


REFUSED = r"--out '.*out' exists and is not an ilc-analysis output directory \(it holds "

#: (case id, set-up of --out, expected exit status, message regex or None)
OUT_CASES = [
    ("users-summary-json", _users_summary, 2,
     REFUSED + r"summary\.json and no \.ilc-analysis-output marker\)"),
    ("marker-is-a-directory", _marker_is_a_directory, 2, REFUSED),
    ("marker-is-a-symlink", _marker_is_a_symlink, 2, REFUSED),
    ("earlier-toolkit-run", _earlier_run, 0, None),
    ("empty", lambda out: out.mkdir(), 0, None),
]


@pytest.mark.parametrize("command", ["simulate", "reproduce", "study"])
@pytest.mark.parametrize("case, setup, status, message", OUT_CASES,
                         ids=[c[0] for c in OUT_CASES])
def test_out_is_replaced_only_if_the_toolkit_wrote_it(capsys, tmp_path, argv_for, command,
                                                      case, setup, status, message):
    out = tmp_path / "out"
    setup(out)
    if case == "earlier-toolkit-run" and command != "simulate":   # issue 35: never another's
        status, message = 2, (r"--out '.*out' holds the output of `ilc-analysis simulate` "
                              r"\(its \.ilc-analysis-output marker\); `ilc-analysis "
                              rf"{command}` would replace it")
    before = _tree(out)
    code = main(argv_for(command, out))
    _, err = capsys.readouterr()
    assert code == status, err
    assert _leftovers(tmp_path) == []
    if status == 2:
        assert "Traceback" not in err
        line = err.strip().splitlines()[-1]
        assert re.search(message, line), line
        assert "choose a new or empty directory" in line
        assert _tree(out) == before                          # byte for byte, nothing added
        return
    summary = json.loads((out / "summary.json").read_text())
    assert summary != {"run": "previous"}                    # the new run's
    marker = (out / _output.OUTPUT_MARKER).read_text()
    if case == "empty" or command != "study":                # a new marker names the command
        assert f"ilc-analysis {command}" in marker and __version__ in marker


def test_out_written_by_the_toolkit_can_be_written_again(capsys, tmp_path, argv_for):
    """The marker a run writes is what lets the next run replace the directory."""
    out = tmp_path / "out"
    assert main(argv_for("simulate", out)) == 0
    (out / "stale.txt").write_text("from the first run's time")
    assert main(argv_for("simulate", out)) == 0
    assert json.loads((out / "summary.json").read_text())["iterations_run"] == 2
    assert not (out / "stale.txt").exists()                     # replaced as a whole
    capsys.readouterr()


def test_a_directory_turned_foreign_during_a_run_is_not_removed(monkeypatch, tmp_path):
    """The check is repeated before the rename: a marker removed while the run wrote (the
    user claimed the directory) makes the run fail and leaves the directory as it is."""
    out = tmp_path / "out"
    _earlier_run(out)
    with pytest.raises(_output.ParameterError, match=r"out_dir '.*out' exists and is not an "
                                                     r"ilc-analysis output directory"), \
            _output.output_directory(out, "out_dir", command="ilc-analysis simulate") as tmp:
        (tmp / "summary.json").write_text("{}")
        (out / _output.OUTPUT_MARKER).unlink()
    assert _tree(out) == {"summary.json": b'{"run": "previous"}\n'}
    assert _leftovers(tmp_path) == []


# ---------------------------------------------------------------------------------------------
# learner state: one --state, two learn calls
# ---------------------------------------------------------------------------------------------
def _learner_files(tmp_path: Path, capsys) -> tuple[Path, Path, Path]:
    """A design, its first ``learn`` call's state, and a measured record for the next call."""
    design = _design(tmp_path / "design.toml")
    state = tmp_path / "state.json"
    assert main(["learn", str(design), "--state", str(state), "--out",
                 str(tmp_path / "u1.csv"), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["iteration"] == 1 == json.loads(state.read_text())["iteration"]
    measured = tmp_path / "y.csv"
    write_input_csv(measured, 0.01 * np.ones((info["record_length"], len(info["output_names"]))),
                    info["output_names"])
    return design, state, measured


#: the barrier each ``learn`` subprocess meets after reading the state: it goes on once the
#: other call has read the state too (the lost update of a run without a lock) or is waiting
#: for the state's lock (a run with one); the timeout only bounds a hang
_BARRIER = textwrap.dedent("""
    import os, sys, time
    from pathlib import Path
    from ilc_analysis.cli import learn_command
    from ilc_analysis.cli.main import main
    from ilc_analysis.simulation import Learner

    me, other, meet = sys.argv[1], sys.argv[2], Path(sys.argv[3])
    original_load = Learner.load_state.__func__

    def load_state(cls, *args, **kwargs):
        learner = original_load(cls, *args, **kwargs)
        (meet / f"read-{me}").touch()
        deadline = time.monotonic() + 600
        while not ((meet / f"read-{other}").exists() or (meet / f"waiting-{other}").exists()):
            if time.monotonic() > deadline:
                break
            time.sleep(0.01)
        return learner

    Learner.load_state = classmethod(load_state)
    if hasattr(learn_command, "held_lock"):
        original_lock = learn_command.held_lock

        def held_lock(*args, **kwargs):
            (meet / f"waiting-{me}").touch()
            return original_lock(*args, **kwargs)

        learn_command.held_lock = held_lock
    sys.exit(main(sys.argv[4:]))
""")


def test_two_concurrent_learn_calls_on_one_state_lose_no_update(tmp_path, capsys):
    design, state, measured = _learner_files(tmp_path, capsys)
    meet = tmp_path / "meet"
    meet.mkdir()
    procs = []
    for me, other in (("a", "b"), ("b", "a")):
        argv = ["learn", str(design), "--state", str(state), "--measured", str(measured),
                "--out", str(tmp_path / f"u-{me}.csv"), "--json"]
        procs.append(subprocess.Popen([sys.executable, "-c", _BARRIER, me, other, str(meet),
                                       *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                      text=True))
    results = []
    for proc in procs:
        try:
            out, err = proc.communicate(timeout=PROCESS_LIMIT)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise
        results.append((proc.returncode, out, err))
    ok = [json.loads(out) for code, out, _ in results if code == 0]
    refused = [err for code, _, err in results if code != 0]
    assert all(code in (0, 2) for code, _, _ in results), results
    for err in refused:                    # refused only by the lock, naming --state
        assert re.search(r"--state '.*state\.json' is being updated by another", err), err
    final = json.loads(state.read_text())
    assert final["iteration"] == 1 + len(ok)             # every call that said 0 counted
    assert sorted(info["iteration"] for info in ok) == list(range(2, 2 + len(ok)))
    # the state belongs to the input written last: it is the state's next input
    last = max(ok, key=lambda info: info["iteration"])
    with open(last["out"]) as f:
        written = np.loadtxt(f, delimiter=",", skiprows=1, ndmin=2)
    np.testing.assert_allclose(written, np.array(final["next_input"]), rtol=0, atol=0)
    assert _leftovers(tmp_path) == []


def test_learn_refuses_a_state_locked_for_too_long(tmp_path, capsys, monkeypatch):
    """Another call holding the lock beyond STATE_LOCK_TIMEOUT: exit 2 naming --state,
    nothing written (the state and --out as they were)."""
    from filelock import FileLock

    design, state, measured = _learner_files(tmp_path, capsys)
    monkeypatch.setattr(learn_command, "STATE_LOCK_TIMEOUT", 0.0)
    before = _tree(tmp_path)
    with FileLock(tmp_path / ".state.json.lock"):
        code = main(["learn", str(design), "--state", str(state), "--measured", str(measured),
                     "--out", str(tmp_path / "u2.csv")])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert re.search(r"--state '.*state\.json' is being updated by another ilc-analysis learn "
                     r"call .*run the command again", err.strip().splitlines()[-1])
    after = _tree(tmp_path)
    after.pop(".state.json.lock", None)                  # the holder's lock file
    assert after == before


def test_a_failed_input_write_leaves_the_state(tmp_path, capsys, monkeypatch):
    """The input is written first: if that fails, the state does not advance."""
    design, state, measured = _learner_files(tmp_path, capsys)
    saved = state.read_bytes()

    def full_disk(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("ilc_analysis.cli._learn_command.write_input_csv", full_disk)
    code = main(["learn", str(design), "--state", str(state), "--measured", str(measured),
                 "--out", str(tmp_path / "u2.csv")])
    assert code == 1 and "No space left" in capsys.readouterr().err
    assert state.read_bytes() == saved and not (tmp_path / "u2.csv").exists()
    assert _leftovers(tmp_path) == []


def test_the_cli_does_not_import_fcntl():
    """fcntl exists on Unix only: the CLI must start without it (filelock locks)."""
    script = ("import sys; sys.modules['fcntl'] = None\n"
              "from ilc_analysis.cli.main import main\n"
              "import ilc_analysis._output, ilc_analysis.cli._learn_command\n"
              "import ilc_analysis.studies._run\n")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=PROCESS_LIMIT)
    assert proc.returncode == 0, proc.stderr


# ---------------------------------------------------------------------------------------------
# studies: markers that prove their chunk
# ---------------------------------------------------------------------------------------------
@pytest.fixture
def small_study(tmp_path) -> Study:
    """20 points, one per chunk (the issue's 19 forged markers fit)."""
    design = _design(tmp_path / "design.toml")
    return Study.from_design(design, [grid("law.forgetting.delta",
                                           list(np.linspace(0.8, 0.98, 20)))],
                             compute=Compute(iterations=2, simulate=False), chunk_size=1)


class _Stop(Exception):
    pass


def _stop_after(n: int):
    def on_chunk(chunk, stored):
        if stored == n:
            raise _Stop
    return on_chunk


def _chunk_file(out: Path, name: str, chunk: int) -> Path:
    return out / "points.zarr" / name / str(chunk)


def test_forged_markers_over_nan_points_are_recomputed(small_study, tmp_path):
    """The issue's case: a run stopped after one chunk, 19 markers forged (empty files, and
    copies of the real marker) over points that hold NaN: the resumed run recomputes the 19
    chunks and says so; no NaN hides behind "failed 0"."""
    out = tmp_path / "out"
    with pytest.raises(_Stop):
        run_study(small_study, out, progress=False, on_chunk=_stop_after(1))
    done = out / "done"
    (real,) = list(done.iterdir())
    for c in range(small_study.n_chunks):
        marker = done / f"chunk-{c:09d}"
        if not marker.exists():
            if c % 2:
                marker.touch()
            else:
                shutil.copy(real, marker)
    run = run_study(small_study, out, progress=False)
    assert run.failed == 0 and np.isfinite(run.dataset["norm_2"]).all()
    assert len(run.recomputed) == 19 and run.resumed == 1 and run.computed == 19
    reasons = set(run.recomputed.values())
    assert any("no content hash" in r for r in reasons)
    assert any("marker of chunk" in r for r in reasons)
    assert "recomputed 19 chunk(s)" in run.summary()
    fresh = run_study(small_study, tmp_path / "fresh", progress=False)
    xr.testing.assert_identical(run.dataset, fresh.dataset)


@pytest.mark.parametrize("damage", ["swapped", "altered", "missing", "marker-edited"])
def test_damaged_chunk_data_is_detected_and_recomputed(small_study, tmp_path, damage):
    out = tmp_path / "out"
    first = run_study(small_study, out, progress=False)
    # the error floor differs from point to point (delta is the axis)
    a, b = _chunk_file(out, "error_floor", 3), _chunk_file(out, "error_floor", 7)
    if damage == "swapped":
        tmp = a.with_name("x")
        a.rename(tmp), b.rename(a), tmp.rename(b)
        expected = {3, 7}
    elif damage == "altered":
        a.write_bytes(a.read_bytes()[:-3] + b"\x00\x01\x02")
        expected = {3}
    elif damage == "missing":
        a.unlink()
        expected = {3}
    else:                                    # a marker rewritten with another hash
        marker = out / "done" / f"chunk-{3:09d}"
        doc = json.loads(marker.read_text())
        marker.write_text(json.dumps({**doc, "sha256": "0" * 64}))
        expected = {3}
    run = run_study(small_study, out, progress=False)
    xr.testing.assert_identical(run.dataset, first.dataset)
    assert set(run.recomputed) == expected
    assert run.computed == len(expected) and run.resumed == small_study.size - len(expected)
    report = json.loads(json.dumps({str(k): v for k, v in run.recomputed.items()}))
    assert all("match" in why or "read" in why for why in report.values())


def test_a_clean_resume_recomputes_nothing(small_study, tmp_path):
    out = tmp_path / "out"
    first = run_study(small_study, out, progress=False)
    again = run_study(small_study, out, progress=False)
    assert again.recomputed == {} and again.computed == 0
    assert again.resumed == small_study.size
    assert "recomputed" not in again.summary()
    xr.testing.assert_identical(again.dataset, first.dataset)


def test_a_marker_holds_the_digest_of_its_chunk(small_study, tmp_path):
    """The marker's hash is the digest of the data read back (computed here from zarr)."""
    import zarr

    from ilc_analysis.studies._evaluate import output_variables
    from ilc_analysis.studies._storage import chunk_digest

    out = tmp_path / "out"
    run_study(small_study, out, progress=False)
    variables = output_variables(small_study)
    group = zarr.open_group(out / "points.zarr", mode="r", zarr_format=2)
    arrays = {name: group[name][5:6] for name in variables}
    marker = json.loads((out / "done" / f"chunk-{5:09d}").read_text())
    assert marker["chunk"] == 5 and marker["points"] == [5, 6]
    assert marker["sha256"] == chunk_digest(small_study, 5, variables, arrays)
    assert marker["sha256"] != chunk_digest(small_study, 6, variables, arrays)


def test_study_cli_reports_recomputed_chunks(tmp_path, capsys):
    """The command's report (text, report.md, summary.json) counts recomputed chunks."""
    _design(tmp_path / "design.toml")
    study_file = tmp_path / "study.toml"
    study_file.write_text(STUDY.replace("count = 3", "count = 1"))
    out = tmp_path / "out"
    argv = ["study", str(study_file), "--out", str(out), "--serial", "--no-progress",
            "--no-figures"]
    assert main(argv) == 0
    (out / "done" / f"chunk-{0:09d}").write_text("")          # forged
    capsys.readouterr()
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "recomputed 1 chunk(s)" in text and "no content hash" in text
    summary = json.loads((out / "summary.json").read_text())
    assert list(summary["recomputed_chunks"]) == ["0"]
    assert "recomputed chunks (marked done, but the stored data failed verification): 1" \
        in (out / "report.md").read_text()
    assert load_study(study_file).n_chunks == 2


# ---------------------------------------------------------------------------------------------
# issue 35: a store with an output missing or its metadata altered; what a store may decode
# ---------------------------------------------------------------------------------------------
def _pickle_codec(meta_path: Path) -> None:
    meta = json.loads(meta_path.read_text())
    meta["compressor"] = {"id": "pickle", "protocol": 5}
    meta_path.write_text(json.dumps(meta))


def _longer(meta_path: Path) -> None:
    meta = json.loads(meta_path.read_text())
    meta["shape"] = [2000000, *meta["shape"][1:]]
    meta_path.write_text(json.dumps(meta))


def _forged_blosc_size(chunk: Path) -> None:
    data = bytearray(chunk.read_bytes())
    data[4:8] = (2**31 - 1).to_bytes(4, "little")       # "decodes to 2 GiB"
    chunk.write_bytes(bytes(data))


def _zlib_bomb(array: Path, chunk: str, inflated: int) -> None:
    """Array ``array``'s compressor made zlib and chunk file ``chunk`` a zlib stream of
    ``inflated`` zero bytes (a chunk file of about inflated / 1000 bytes)."""
    import zlib

    meta = json.loads((array / ".zarray").read_text())
    meta["compressor"] = {"id": "zlib", "level": 9}
    (array / ".zarray").write_text(json.dumps(meta))
    z, block = zlib.compressobj(9), bytes(2**20)
    with open(array / chunk, "wb") as f:
        for _ in range(inflated // len(block)):
            f.write(z.compress(block))
        f.write(z.flush())


def _uncompressed_longer(array: Path, chunk: str) -> None:
    meta = json.loads((array / ".zarray").read_text())
    meta["compressor"] = None
    (array / ".zarray").write_text(json.dumps(meta))
    (array / chunk).write_bytes(bytes(16))


STORE_DAMAGE = [
    ("zlib chunk", lambda out: _zlib_bomb(out / "points.zarr" / "norm_2", "4", 2**20),
     r"array 'norm_2' names the codec 'zlib', which is never decoded \(only blosc, whose "
     r"chunks declare their decoded size\)"),
    ("uncompressed chunk past its size",
     lambda out: _uncompressed_longer(out / "points.zarr" / "norm_2", "4"),
     r"chunk file norm_2/\d+ declares (16|24) bytes; its chunk holds 8"),   # 24: blosc's
    ("output array missing", lambda out: shutil.rmtree(out / "points.zarr" / "norm_2"),
     r"output 'norm_2' is missing from points\.zarr"),
    ("pickle codec", lambda out: _pickle_codec(out / "points.zarr" / "norm_2" / ".zarray"),
     r"array 'norm_2' names the codec 'pickle', which is never decoded"),
    ("shape changed", lambda out: _longer(out / "points.zarr" / "norm_2" / ".zarray"),
     r"the metadata of output 'norm_2' is not what this study writes"),
    ("forged blosc header", lambda out: _forged_blosc_size(_chunk_file(out, "norm_2", 4)),
     r"chunk file norm_2/4 declares 2147483647 bytes; its chunk holds 8"),
    ("unknown array", lambda out: shutil.copytree(out / "points.zarr" / "norm_2",
                                                  out / "points.zarr" / "extra"),
     r"points\.zarr holds 'extra', which this study does not write"),
]


@pytest.fixture
def five_points(tmp_path) -> Study:
    """5 points, one per chunk: enough chunks that the damaged chunk file (norm_2/4) exists and
    every chunk must be recomputed, at a quarter of small_study's cost."""
    design = _design(tmp_path / "design.toml")
    return Study.from_design(design, [grid("law.forgetting.delta",
                                           list(np.linspace(0.8, 0.98, 5)))],
                             compute=Compute(iterations=2, simulate=False), chunk_size=1)


@pytest.mark.parametrize("damage, why", [c[1:] for c in STORE_DAMAGE],
                         ids=[c[0] for c in STORE_DAMAGE])
def test_a_damaged_store_is_rebuilt_and_every_chunk_recomputed(five_points, tmp_path, damage,
                                                                why):
    """Issue 35: a store missing one output array could never be resumed (every chunk
    rejected, then a KeyError traceback on every run until --restart). Now any store whose
    structure is not what the study writes is rebuilt, before a chunk is decoded (a pickle
    codec would unpickle a chunk file; a forged blosc header would allocate what it claims),
    every chunk computed again and the reason reported; the results equal a fresh run."""
    out = tmp_path / "out"
    first = run_study(five_points, out, progress=False)
    damage(out)
    run = run_study(five_points, out, progress=False)
    assert run.computed == five_points.size and run.resumed == 0
    assert len(run.recomputed) == five_points.n_chunks
    assert all(re.search(why, r) for r in run.recomputed.values()), run.recomputed
    xr.testing.assert_identical(run.dataset, first.dataset)
    again = run_study(five_points, out, progress=False)           # and it resumes from now on
    assert again.computed == 0 and again.recomputed == {}


def test_study_cli_resumes_a_store_missing_an_output(tmp_path, capsys):
    """The issue's case on the command line: exit 0 both times, no traceback, the reason."""
    _design(tmp_path / "design.toml")
    study = tmp_path / "study.toml"
    study.write_text(STUDY.replace("count = 3", "count = 1"))
    argv = ["study", str(study), "--out", str(tmp_path / "out"), "--serial", "--no-progress",
            "--no-figures"]
    assert main(argv) == 0
    shutil.rmtree(tmp_path / "out" / "points.zarr" / "max_error")
    capsys.readouterr()
    assert main(argv) == 0
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    assert "output 'max_error' is missing from points.zarr" in out
    assert main(argv) == 0 and "resumed" in capsys.readouterr().out


def test_open_results_refuses_a_pickle_codec(small_study, tmp_path):
    from ilc_analysis.exceptions import ParameterError
    from ilc_analysis.studies import open_results

    out = tmp_path / "out"
    run_study(small_study, out, progress=False)
    _pickle_codec(out / "results.zarr" / "norm_2" / ".zarray")
    with pytest.raises(ParameterError, match=r"results\.zarr': array 'norm_2' names the codec "
                                             r"'pickle', which is never decoded"):
        open_results(out)


def _huge_shape(array: Path) -> None:
    meta = json.loads((array / ".zarray").read_text())
    meta["shape"] = [10**12]
    (array / ".zarray").write_text(json.dumps(meta))


RESULTS_DAMAGE = [
    # 2 GiB of zeros in a 2 MB zlib chunk: decoded, it would take the memory limit below
    ("zlib bomb", lambda out: _zlib_bomb(out / "results.zarr" / "norm_2", "0", 2**31),
     r"array 'norm_2' names the codec 'zlib', which is never decoded"),
    ("forged blosc header",
     lambda out: _forged_blosc_size(out / "results.zarr" / "norm_2" / "0"),
     r"chunk file norm_2/0 declares 2147483647 bytes; its chunk holds \d+"),
    ("missing chunks of a huge array", lambda out: _huge_shape(out / "results.zarr" / "norm_2"),
     r"array 'norm_2' has shape \[1000000000000\] of <f8, more than MAX_ARRAY_BYTES"),
]


@pytest.mark.parametrize("damage, why", [c[1:] for c in RESULTS_DAMAGE],
                         ids=[c[0] for c in RESULTS_DAMAGE])
def test_open_results_decodes_nothing_unbounded(small_study, tmp_path, damage, why):
    """Issue 35: every codec zarr allows but blosc decodes a chunk whole, however large (a
    zlib chunk of 2 MB inflates to 2 GiB), and an array whose chunks are missing is filled to
    its shape: open_results refuses both before decoding, in a process whose address space is
    limited to 1 GiB more than it holds."""
    out = tmp_path / "out"
    run_study(small_study, out, progress=False)
    damage(out)
    code = (
        "import resource, re, sys\n"
        "from ilc_analysis.exceptions import ParameterError\n"
        "from ilc_analysis.studies import open_results\n"
        "import xarray, zarr\n"
        "here = int(open('/proc/self/statm').read().split()[0]) * resource.getpagesize()\n"
        "resource.setrlimit(resource.RLIMIT_AS, (here + 2**30, resource.RLIM_INFINITY))\n"
        "try:\n"
        "    open_results(sys.argv[1])\n"
        "except ParameterError as exc:\n"
        "    print(exc)\n"
        "    sys.exit(0 if re.search(sys.argv[2], str(exc)) else 3)\n"
        "sys.exit(4)\n")
    if not Path("/proc/self/statm").exists():
        pytest.skip("the memory bound reads /proc/self/statm (Linux)")
    done = subprocess.run([sys.executable, "-c", code, str(out), why], capture_output=True,
                          text=True, timeout=300, check=False,
                          env={**os.environ, "OPENBLAS_NUM_THREADS": "1",
                               "MALLOC_ARENA_MAX": "2"})
    assert done.returncode == 0, (done.returncode, done.stdout[-500:], done.stderr[-2000:])


def test_the_api_tracks_no_inputs_and_the_cli_does(tmp_path, capsys):
    """Outside the command line a session may read a design and later write the same path
    (save_design replaces a design file); inside it, a run never replaces what it read."""
    from ilc_analysis.design import load_design, save_design

    path = _design(tmp_path / "design.toml")
    design = load_design(path).certify()
    save_design(design, path)                             # the API: allowed
    assert load_design(path).certificate is not None
    with _output.tracking_inputs():
        load_design(path)
        with pytest.raises(_output.ParameterError, match=r"is design file .*which this run "
                                                         r"reads"):
            save_design(design, path)


def test_save_design_refuses_to_replace_a_file_that_is_not_a_design(tmp_path):
    from ilc_analysis.design import load_design, save_design

    design = load_design(_design(tmp_path / "design.toml"))
    target = tmp_path / "pyproject.toml"
    target.write_text('[project]\nname = "mine"\n')
    with pytest.raises(_output.ParameterError, match=r"exists and is a TOML file that is not a "
                                                     r"design file \(it holds project"):
        save_design(design, target)
    assert target.read_text() == '[project]\nname = "mine"\n'
