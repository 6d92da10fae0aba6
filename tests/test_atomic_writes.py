"""Nothing half-written (issue 16): outputs go to a temporary file beside the target and
are renamed into place, so a killed or failed `navsim simulate` leaves the previous file
intact (kill tests with SIGKILL in the middle of the write)."""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import sys

import numpy as np
import pytest

from navsim.cli import main
from navsim.io import atomic_output

KILLER = """
import os, signal, sys
import numpy as np
import navsim.io as nio
mode = sys.argv[1]
if mode == "npz":  # die while the zip is being written (after the first array's header)
    original = np.lib.format.write_array_header_1_0
    calls = []
    def header(*a, **k):
        calls.append(1)
        if len(calls) == 3:
            os.kill(os.getpid(), signal.SIGKILL)
        return original(*a, **k)
    np.lib.format.write_array_header_1_0 = header
else:  # die after the first chunk's rows were written
    original = nio.chunk_arrays
    calls = []
    def arrays(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            os.kill(os.getpid(), signal.SIGKILL)
        return original(*a, **k)
    nio.chunk_arrays = arrays
from navsim.cli import main
main(sys.argv[2:])
"""


@pytest.mark.parametrize("fmt", ["npz", "csv"])
def test_simulate_killed_during_the_write_keeps_the_previous_file(tmp_path, fmt):
    out = tmp_path / f"episode.{fmt}"
    assert main(["simulate", "paper-2012", "--set", "timing.duration_s=2", "-q", "-o", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    argv = ["simulate", "paper-2012", "--set", "timing.duration_s=4", "--seed", "5", "--chunk", "100", "-q",
            "-o", str(out)]
    proc = subprocess.run([sys.executable, "-c", KILLER, fmt, *argv], capture_output=True, timeout=300)
    assert proc.returncode == -signal.SIGKILL, proc.stderr.decode()[-2000:]
    after = {p.name: p.read_bytes() for p in tmp_path.iterdir() if not p.name.endswith(".part")}
    assert after == before  # the previous file(s), byte for byte; at most a .part beside them
    if fmt == "npz":
        with np.load(out) as data:
            assert data["t"].shape == (200,)


def test_failed_write_removes_its_temporary_and_keeps_the_target(tmp_path):
    target = tmp_path / "x.bin"
    target.write_bytes(b"previous")
    with pytest.raises(OSError):
        with atomic_output(target) as fh:
            fh.write(b"half")
            raise OSError(28, "No space left on device")  # what a full disk raises
    assert target.read_bytes() == b"previous"
    assert [p.name for p in tmp_path.iterdir()] == ["x.bin"]
    with atomic_output(target) as fh:
        fh.write(b"new")
    assert target.read_bytes() == b"new" and [p.name for p in tmp_path.iterdir()] == ["x.bin"]


PLOT_KILLER = """
import os, signal, sys
import matplotlib
matplotlib.use("Agg")
from matplotlib.figure import Figure
original = Figure.savefig
def savefig(self, fname, *a, **k):
    fname.write(b"\\x89PNG half a plot")  # a partial image, then the process dies mid-save
    fname.flush()
    os.kill(os.getpid(), signal.SIGKILL)
Figure.savefig = savefig
from navsim.plots import plot_outage_drifts
plot_outage_drifts({}, sys.argv[1], title="second")
"""


def test_plot_killed_during_the_save_keeps_the_previous_image(tmp_path):
    pytest.importorskip("matplotlib")
    from navsim.plots import plot_outage_drifts

    out = tmp_path / "bench_outages.png"
    plot_outage_drifts({}, out, title="first")
    before = out.read_bytes()
    assert before.startswith(b"\x89PNG\r\n\x1a\n")
    proc = subprocess.run([sys.executable, "-c", PLOT_KILLER, str(out)], capture_output=True, timeout=300)
    assert proc.returncode == -signal.SIGKILL, proc.stderr.decode()[-2000:]
    assert out.read_bytes() == before  # the previous image whole; at most a .part beside it
    assert all(p.name == out.name or p.name.endswith(".part") for p in tmp_path.iterdir())



@pytest.mark.skipif(os.name != "posix", reason="POSIX permission bits")
def test_written_files_get_the_permissions_of_an_ordinary_open(tmp_path):
    """A new file: 0o666 less the umask (not mkstemp's 0o600); a replaced file keeps its mode."""
    old = os.umask(0o022)
    try:
        with atomic_output(tmp_path / "new.bin") as fh:
            fh.write(b"x")
        with open(tmp_path / "plain.bin", "wb") as fh:  # what open() gives under the same umask
            fh.write(b"x")
        assert stat.S_IMODE(os.stat(tmp_path / "new.bin").st_mode) == stat.S_IMODE(
            os.stat(tmp_path / "plain.bin").st_mode) == 0o644
        os.chmod(tmp_path / "new.bin", 0o640)
        with atomic_output(tmp_path / "new.bin") as fh:
            fh.write(b"y")
        assert stat.S_IMODE(os.stat(tmp_path / "new.bin").st_mode) == 0o640
        assert (tmp_path / "new.bin").read_bytes() == b"y"
    finally:
        os.umask(old)
