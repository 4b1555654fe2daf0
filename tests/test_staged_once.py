"""A file is staged once: a writer handed a staged path writes it in place, so that a run killed while it saves a
figure leaves one staged file, which the next run removes (and the nested ones earlier versions left)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from dynamics.runtime.output_files import OutputFiles, is_staged, save_figure

ROOT = Path(__file__).resolve().parents[1]


def test_a_staged_figure_is_written_in_place_not_staged_again(tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure = plt.figure()
    seen: list[list[str]] = []
    original = type(figure).savefig

    def listing_savefig(self, *args, **kwargs):
        seen.append(sorted(os.listdir(tmp_path)))
        return original(self, *args, **kwargs)

    monkeypatch.setattr(type(figure), "savefig", listing_savefig)
    target = tmp_path / "report.trace.png"
    with OutputFiles() as outputs:
        staged = outputs.stage_figure(target)
        assert is_staged(staged) and not is_staged(target)
        save_figure(figure, staged)
    plt.close(figure)
    assert len(seen) == 1 and len(seen[0]) == 1 and seen[0][0].startswith(".report.trace.png.oed-")
    assert sorted(os.listdir(tmp_path)) == ["report.trace.png"] and target.stat().st_size > 0


KILLED_WHILE_SAVING = textwrap.dedent("""
    import sys, time
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from dynamics.runtime.output_files import OutputFiles, save_figure

    figure = plt.figure()
    def stalled(*args, **kwargs):
        print("saving", flush=True)
        time.sleep(120)
    figure.savefig = stalled
    with OutputFiles() as outputs:
        save_figure(figure, outputs.stage_figure(sys.argv[1]))
""")


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="SIGKILL is POSIX")
def test_a_run_killed_while_saving_a_figure_leaves_one_staged_file_that_the_next_run_removes(tmp_path):
    target = tmp_path / "report.trace.png"
    environment = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    process = subprocess.Popen([sys.executable, "-c", KILLED_WHILE_SAVING, str(target)], stdout=subprocess.PIPE,
                               text=True, env=environment)
    try:
        assert process.stdout.readline().strip() == "saving"
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait()
    left = sorted(os.listdir(tmp_path))
    assert len(left) == 1 and left[0].startswith(f".report.trace.png.oed-{process.pid}-"), left
    with OutputFiles() as outputs, outputs.open(target, "wb") as stream:
        stream.write(b"png")
    assert sorted(os.listdir(tmp_path)) == ["report.trace.png"]


def test_a_file_staged_twice_by_an_earlier_version_is_removed_by_the_next_run(tmp_path):
    finished = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                              text=True, check=True)
    gone = int(finished.stdout)  # a process that has ended
    nested = tmp_path / f"..report.trace.png.oed-{gone}-abc.png.oed-{gone}-def.png"
    nested.write_bytes(b"half a figure")
    with OutputFiles() as outputs, outputs.open(tmp_path / "report.trace.png", "wb") as stream:
        stream.write(b"png")
    assert sorted(os.listdir(tmp_path)) == ["report.trace.png"]
