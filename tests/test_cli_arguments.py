"""Every bad command-line value ends in one line naming it, exit 2, no traceback, and nothing written."""

import subprocess
import sys

import pytest

from sandbox.app.cli import EXIT_BAD_INPUT, main
from tests.conftest import ROOT

RUN = ["run", "spring_lattice", "--headless", "--quiet"]


@pytest.mark.parametrize(
    "extra, expected",
    [
        (["--frames", "0"], "--frames 0: expected an integer from 1"),
        (["--frames", "-1"], "--frames -1: expected an integer from 1"),
        (["--substeps", "0"], "--substeps 0: expected an integer from 1"),
        (["--substeps", "-3"], "--substeps -3: expected an integer from 1"),
        (["--width", "0"], "--width 0: expected an integer from 16"),
        (["--width", "-5"], "--width -5: expected an integer from 16"),
        (["--width", "100000"], "--width 100000: expected an integer from 16 to 8,192"),
        (["--height", "9"], "--height 9: expected an integer from 16"),
        (["--fps", "0"], "--fps 0.0: expected a number above 0"),
        (["--fps", "nan"], "--fps nan: expected a number above 0"),
        (["--fps", "inf"], "--fps inf: expected a number above 0"),
        (["--still-frame", "3"], "--still-frame 3: expected together with a .png --out"),
        (["--still-frame", "1000", "--out", "{tmp}/s.png"], "--still-frame 1000: expected an integer from 0 to 239"),
        (["--still-frame", "-1", "--out", "{tmp}/s.png"], "--still-frame -1: expected an integer from 0"),
        (["--width", "101", "--out", "{tmp}/v.mp4"], "expected even numbers for .mp4 video"),
        (["--out", "{tmp}/v.avi"], "unknown output kind '.avi'"),
        (["--out", "/proc/x/y.mp4"], "cannot write in '/proc/x'"),
        (["--stats", "/proc/x/s.csv"], "cannot write in '/proc/x'"),
        (["--out", "{tmp}/file.txt/x.mp4"], "exists and is not a folder"),
        (["--out", "{tmp}/file.txt"], "unknown output kind '.txt'"),
        (["--out", "{tmp}/plain"], "is a file; expected a folder for PNG frames"),
        (["--stats", "{tmp}/sub"], "is a folder; expected a file name"),
        (["--out", "{tmp}/a.mp4", "--stats", "{tmp}/a.mp4"], "the same file as --out"),
        (["--screenshot", "{tmp}/s.jpg"], "expected a file ending in .png"),
        (["--set", "world.dt=-1"], "key 'world.dt': expected a number > 0"),
        (["--set", "world.dt"], "key 'world.dt': expected key=value"),
    ],
)
def test_bad_values_give_one_line_and_exit_2_writing_nothing(extra, expected, tmp_path, capsys):
    (tmp_path / "file.txt").write_text("x")
    (tmp_path / "plain").write_text("x")
    (tmp_path / "sub").mkdir()
    before = sorted(tmp_path.rglob("*"))
    args = [a.replace("{tmp}", str(tmp_path)) for a in extra]
    assert main(RUN + args) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    assert expected in err[0]
    assert sorted(tmp_path.rglob("*")) == before  # nothing written, no folder made


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["study", "--out", "{tmp}/plain"], "--out {tmp}/plain: is a file; expected a folder"),
        (["study", "--out", "/proc/x"], "--out /proc/x: cannot write in '/proc/x'"),
        (["bench", "--repeats", "0"], "--repeats 0: expected an integer from 1"),
        (["bench", "--json", "{tmp}/b.txt"], "expected a file ending in .json"),
        (["bench", "--scaling", "--out", "{tmp}/plain"], "is a file; expected a folder"),
        (["bench", "--serve", "0"], "--serve: expected a number of sessions of at least 1"),
        (["bench", "--side", "50"], "--side: only with --3d or --contended"),
        (["bench", "--3d", "--side", "101"], "--side 101: expected an integer from 8 to 100"),
        (["bench", "--contended", "--side", "4"], "--side 4: expected an integer from 8 to 1,000"),
        (["bench", "--contended", "0"], "--contended 0: expected an integer from 1 to 16"),
        (["bench", "--contended", "40"], "--contended 40: expected an integer from 1 to 16"),
        (["bench", "--rounds", "3"], "--rounds: only with --lammps"),
        (["bench", "--lammps", "--rounds", "0"], "--rounds 0: expected an integer from 1 to 50"),
        (["serve", "{tmp}/plain"], "unknown scene"),
        (["serve", "--port", "70000"], "--port: expected 1 to 65535"),
        (["serve", "--max-sessions", "0"], "--max-sessions: expected at least 1"),
        (["serve", "--max-fps", "500"], "--max-fps: expected 1 to 60"),
        (["serve", "--token", "short"], "--token: expected at least 8 characters"),
        (["serve", "--per-client", "-1"], "--per-client: expected 0 (no limit) or more sessions, got -1"),
        (["serve", "--idle", "5"], "--idle: expected 60 to 86400 seconds, got 5"),
        (["serve", "--idle", "nan"], "--idle: expected 60 to 86400 seconds, got nan"),
        # issue 72: study modes at once, options a study does not read, empty or repeated temperatures
        (["study", "--out", "{tmp}/s", "--coexistence", "--heating"], "--coexistence and --heating: one study a run"),
        (["study", "--out", "{tmp}/s", "--heating", "--scheduler", "tcp://127.0.0.1:1"], "--scheduler with --heating"),
        (["study", "--out", "{tmp}/s", "--phase", "--workers", "2", "--threads", "1"], "--workers, --threads with"),
        (["study", "--out", "{tmp}/s", "--heating", "--temperatures", "0.7"], "--temperatures with --heating"),
        (["study", "--out", "{tmp}/s", "--triple", "--workers", "2"], "--workers with --triple"),
        (["study", "--out", "{tmp}/s", "--triple", "--phase"], "--phase and --triple: one study a run"),
        (["study", "--out", "{tmp}/s", "--integrators", "rk4", "--coexistence"], "--integrators with --coexistence"),
        (["study", "--out", "{tmp}/s", "--coexistence", "--temperatures", ""], "--temperatures: empty"),
        (["study", "--out", "{tmp}/s", "--coexistence", "--temperatures", "0.7,0.8,0.7"], "0.7 given twice"),
    ],
)
def test_study_and_bench_check_their_arguments_first(argv, expected, tmp_path, capsys):
    (tmp_path / "plain").write_text("x")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(argv) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ")
    assert expected.replace("{tmp}", str(tmp_path)) in err[0]


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["--cache", "-w.ply"], "argument --cache: expected one argument; a value beginning with '-' is written"),
        (["--cache-every", "abc"], "argument --cache-every: invalid int value: 'abc'"),
        (["--dim", "4"], "unrecognized arguments: --dim 4"),
        (["--arch", "tpu"], "argument --arch: invalid choice: 'tpu'"),
    ],
)
def test_what_argparse_refuses_is_one_line_too(argv, expected, tmp_path, capsys):
    """argparse's own refusals printed its usage text before the error (issue 72): one line now, exit 2."""
    with pytest.raises(SystemExit) as stop:
        main([*RUN, "--frames", "1", "--out", str(tmp_path / "s.png"), *argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert stop.value.code == EXIT_BAD_INPUT
    assert len(err) == 1 and err[0].startswith("error: ") and expected in err[0], err
    assert not list(tmp_path.iterdir())


def test_a_missing_output_folder_is_created_before_the_run(tmp_path, capsys):
    out = tmp_path / "new" / "deeper" / "still.png"
    stats = tmp_path / "other" / "s.csv"
    args = ["--frames", "1", "--width", "32", "--height", "32", "--out", str(out), "--stats", str(stats)]
    assert main(RUN + args) == 0
    assert out.is_file() and stats.is_file()
    assert not list(tmp_path.rglob(".*partial*"))


def test_the_real_command_prints_no_traceback(tmp_path):
    """In a process of its own: an unavailable backend named explicitly, and a value argparse rejects."""
    cases = [
        (["--arch", "cuda", "--frames", "1"], 2, "--arch cuda: the cuda backend is not available"),
        (["--frames", "ten"], 2, "argument --frames: invalid int value: 'ten'"),
    ]
    for extra, code, expected in cases:
        done = subprocess.run(
            [sys.executable, "-m", "sandbox", *RUN, *extra],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=300,
            env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
        )
        if "cuda" in extra and done.returncode == 0:
            pytest.skip("this machine has CUDA")
        assert done.returncode == code, done.stderr
        assert "Traceback" not in done.stderr and expected in done.stderr
        assert done.stdout == ""
    assert list(tmp_path.iterdir()) == []


def test_a_bad_thread_count_in_the_environment_is_one_line(tmp_path):
    """SANDBOX_CPU_THREADS=0 crashed Taichi (a floating-point exception), a word raised a traceback, and a huge count
    would start that many threads: each is now one line and exit status 2, before anything runs."""
    for value in ("0", "abc", "100000", "-2", "²"):
        done = subprocess.run(
            [sys.executable, "-m", "sandbox", "check", str(ROOT / "scenes" / "lj_box.toml")],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=300,
            env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin", "SANDBOX_CPU_THREADS": value},
        )
        assert done.returncode == 2, (value, done.returncode, done.stderr[-500:])
        assert (
            done.stderr.strip()
            == f"error: SANDBOX_CPU_THREADS='{value}': expected a whole number of threads from 1 to 256"
        )
        assert done.stdout == ""


def test_a_plain_bench_runs_the_workloads_not_one_of_its_only_modes():
    """`sandbox bench` with no mode flag is the whole bench: --serve, --3d, --contended, --window and --scaling are
    off (a default of 0 for --serve once sent every plain bench to the --serve check)."""
    from sandbox.app.cli import build_parser

    args = build_parser().parse_args(["bench"])
    assert args.serve is None and not (args.three_d or args.contended or args.window or args.scaling)
    args = build_parser().parse_args(["bench", "--lammps", "--3d", "--contended"])
    assert args.three_d and args.contended == 1 and args.lammps  # one hog unless told how many
    assert build_parser().parse_args(["bench", "--contended", "3"]).contended == 3
