"""The streamed CSV: exact numbers, rows on disk within the flush interval, every row kept, none torn.

The stream buffers rows and formats them in bulk (sim/csv_stream.py); these tests hold it to the
promise the unbuffered writer kept: rows visible while the run goes on (within 50 ms), every
accepted row on disk after an interruption or an error, never a torn or repeated row, and never
a write through a symlink.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from mbctl.sim import csv_stream
from mbctl.sim.csv_stream import FLUSH_INTERVAL_S, CsvStream, format_rows
from mbctl.sim.exceptions import OutputPathError
from mbctl.sim.recorder import read_csv


def _lines(path):
    return path.read_bytes().decode().splitlines()


def _wait_for_lines(path, n, timeout_s=5.0):
    """Poll until the file holds ``n`` lines; returns the seconds it took (or fails)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        if path.read_bytes().count(b"\n") >= n:
            return time.monotonic() - t0
        time.sleep(0.005)
    have = path.read_bytes().count(b"\n")
    raise AssertionError(f"{path.name} holds {have} lines, not {n}")


@settings(max_examples=200)
@given(hnp.arrays(np.float64, hnp.array_shapes(min_dims=2, max_dims=2, max_side=6),
                  elements=st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)))
def test_every_float_reads_back_bit_for_bit(block):
    text = format_rows(np.ascontiguousarray(block)).decode()
    lines = text.split("\n")
    assert lines[-1] == "" and len(lines) == block.shape[0] + 1  # every line ends in a newline
    back = np.array([[float(x) for x in line.split(",")] for line in lines[:-1]]).reshape(block.shape)
    same = (back.view(np.int64) == block.view(np.int64)) | (np.isnan(back) & np.isnan(block))
    assert same.all()


def test_the_digits_are_repr_s():
    values = np.array([[0.1, -0.0, 1.0 / 3.0, 1e16, 5e-324, 12345.678, 2.0]])
    assert format_rows(values).decode() == ",".join(repr(v) for v in values[0].tolist()) + "\n"
    assert format_rows(np.array([[np.nan, np.inf, -np.inf]])) == b"nan,inf,-inf\n"
    assert float(format_rows(np.array([[1e-5]]))) == 1e-5  # 0.00001: another notation, same double


def test_rows_reach_the_disk_within_the_interval_while_the_stream_is_open(tmp_path):
    path = tmp_path / "run.csv"
    with CsvStream(path, ["time_s", "x_m"]) as stream:
        stream.write([0.0, 1.5])
        stream.write(np.array([0.002, 2.5]))
        waited = _wait_for_lines(path, 3)  # the header and both rows, the stream still open
        assert not stream.closed
        assert _lines(path) == ["time_s,x_m", "0.0,1.5", "0.002,2.5"]
        stream.write([0.004, 3.5])
        _wait_for_lines(path, 4)
    assert waited < 1.0, f"rows waited {waited:.3f} s (interval {FLUSH_INTERVAL_S} s)"
    assert _lines(path)[-1] == "0.004,3.5" and stream.rows == 3


def test_a_stream_keeps_every_row_of_a_long_run_exactly(tmp_path):
    rng = np.random.default_rng(0)
    rows = rng.standard_normal((20_000, 7)) * 10.0 ** rng.integers(-8, 8, (20_000, 7))
    path = tmp_path / "long.csv"
    with CsvStream(path, [f"c{i}" for i in range(7)]) as stream:
        for k, row in enumerate(rows):  # past the first block: it grows, the thread flushes
            stream.write(row)
            if k % 5000 == 0:
                time.sleep(2 * FLUSH_INTERVAL_S)
    data = read_csv(path)
    np.testing.assert_array_equal(np.column_stack([data[f"c{i}"] for i in range(7)]), rows)
    assert stream.rows == 20_000 and np.array_equal(stream.last, rows[-1])


def test_a_flush_cut_short_leaves_no_torn_and_no_repeated_row(tmp_path, monkeypatch):
    """Ctrl-C inside a flush (after half its bytes, or after all of them but before the book-keeping)."""
    real = csv_stream._pwrite_all
    for cut in ("half", "all"):
        calls = []

        def interrupted(fd, data, offset, cut=cut, calls=calls):
            if len(calls) == 1:  # the second write (the first is the header): cut it
                calls.append(offset)
                real(fd, data[: len(data) // 2] if cut == "half" else data, offset)
                raise KeyboardInterrupt
            calls.append(offset)
            real(fd, data, offset)

        monkeypatch.setattr(csv_stream, "_pwrite_all", interrupted)
        path = tmp_path / f"{cut}.csv"
        stream = CsvStream(path, ["k", "x"], flush_interval_s=10.0)
        for k in range(100):
            stream.write([float(k), k / 7.0])
        with pytest.raises(KeyboardInterrupt):
            stream.flush()
        stream.write([100.0, 100 / 7.0])  # the run went on after the interruption was handled
        stream.close()
        lines = _lines(path)
        assert len(lines) == 102 and all(line.count(",") == 1 for line in lines), cut
        np.testing.assert_array_equal(read_csv(path)["k"], np.arange(101.0))
        np.testing.assert_array_equal(read_csv(path)["x"], np.arange(101.0) / 7.0)


def test_rows_are_kept_on_an_exception_and_on_ctrl_c(tmp_path):
    for error in (RuntimeError("boom"), KeyboardInterrupt()):
        path = tmp_path / f"{type(error).__name__}.csv"
        with pytest.raises(type(error)):
            with CsvStream(path, ["k"], flush_interval_s=10.0) as stream:  # nothing flushed before
                for k in range(1000):
                    stream.write([float(k)])
                raise error
        np.testing.assert_array_equal(read_csv(path)["k"], np.arange(1000.0))


def test_rows_are_kept_when_the_interpreter_exits_without_close(tmp_path):
    path = tmp_path / "exit.csv"
    script = (
        "from mbctl.sim.csv_stream import CsvStream\n"
        f"s = CsvStream({str(path)!r}, ['k'], flush_interval_s=1000.0)\n"
        "for k in range(500): s.write([float(k)])\n"
    )
    subprocess.run([sys.executable, "-c", script], check=True, timeout=120)
    np.testing.assert_array_equal(read_csv(path)["k"], np.arange(500.0))


def test_sigterm_mid_run_keeps_every_row_and_no_torn_one(tmp_path):
    """A run in another process, killed by SIGTERM while it streams rows (the runner's handling)."""
    folder = tmp_path / "run"
    script = (
        "import numpy as np\n"
        "from mbctl.jobs.runner import Job, Outcome, run_job\n"
        "def prepare(params):\n"
        "    def work(ctx):\n"
        "        csv = ctx.open_csv(['time_s'] + [f'x{i}' for i in range(40)])\n"
        "        rng = np.random.default_rng(1)\n"
        "        for k in range(10**8):\n"
        "            csv.write(np.r_[0.001 * k, rng.standard_normal(40)])\n"
        "        return Outcome()\n"
        "    return work\n"
        f"record = run_job(Job('toy', prepare), None, {str(folder)!r})\n"
        "print(record.status, record.rows)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    path = folder / "toy.csv"
    # rows on disk mid-run (the child streams until it is stopped: it ends only by failing)
    while not (path.exists() and path.read_bytes().count(b"\n") > 1000):
        assert proc.poll() is None, "the run ended before it streamed any rows"
        time.sleep(0.01)
    proc.terminate()
    out, _ = proc.communicate(timeout=60)
    status, rows = out.split()
    assert status == "interrupted"
    lines = _lines(path)
    assert len(lines) == int(rows) + 1 > 1001
    assert all(line.count(",") == 40 for line in lines)  # no torn row
    rng = np.random.default_rng(1)
    expected = np.array([np.r_[0.001 * k, rng.standard_normal(40)] for k in range(int(rows))])
    data = read_csv(path)
    np.testing.assert_array_equal(np.column_stack(list(data.values())), expected)  # exact, none repeated


def test_a_symlink_at_the_path_is_refused_and_its_target_untouched(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    link = tmp_path / "out" / "run.csv"
    link.parent.mkdir()
    link.symlink_to(victim)
    with pytest.raises(OutputPathError, match="run.csv is a symbolic link .*never written through a link"):
        CsvStream(link, ["time_s"])
    assert victim.read_text() == "precious" and link.is_symlink()
    link.unlink()
    link.mkdir()
    with pytest.raises(OutputPathError, match="run.csv exists and is not a regular file"):
        CsvStream(link, ["time_s"])
    link.rmdir()
    os.mkfifo(link)
    with pytest.raises(OutputPathError, match="run.csv exists and is not a regular file"):
        CsvStream(link, ["time_s"])
    link.unlink()
    link.parent.chmod(0o500)
    try:
        if not os.access(link.parent, os.W_OK):  # root writes anywhere: nothing to refuse then
            with pytest.raises(OutputPathError, match="cannot create .*run.csv: Permission denied"):
                CsvStream(link, ["time_s"])
    finally:
        link.parent.chmod(0o700)


def test_bad_rows_and_writes_after_close_are_refused(tmp_path):
    stream = CsvStream(tmp_path / "a.csv", ["a", "b"])
    with pytest.raises(ValueError, match="a row of a.csv has 2 values; got 3"):
        stream.write([1.0, 2.0, 3.0])
    stream.close()
    with pytest.raises(ValueError, match="a.csv is closed"):
        stream.write([1.0, 2.0])
    assert stream.rows == 0 and _lines(tmp_path / "a.csv") == ["a,b"]
    with pytest.raises(ValueError, match="flush_interval_s must be finite and >= 0"):
        CsvStream(tmp_path / "b.csv", ["a"], flush_interval_s=-1.0)


def test_a_failed_flush_in_the_thread_is_raised_by_the_next_write(tmp_path, monkeypatch):
    def full(fd, data, offset):
        raise OSError(28, "No space left on device")

    stream = CsvStream(tmp_path / "a.csv", ["a"])
    monkeypatch.setattr(csv_stream, "_pwrite_all", full)
    stream.write([1.0])
    t0 = time.monotonic()
    while stream._error is None and time.monotonic() - t0 < 5.0:
        time.sleep(0.01)
    with pytest.raises(OSError, match="No space left"):
        stream.write([2.0])
    with pytest.raises(OSError, match="No space left"):
        stream.close()
    assert stream.closed


def test_blocks_of_rows_are_kept_exactly_however_they_fit_the_buffer(tmp_path, monkeypatch):
    monkeypatch.setattr(csv_stream, "_BLOCK_MAX_BYTES", 8 * 3 * 100)  # at most 100 rows of 3 buffered
    rng = np.random.default_rng(1)
    rows = rng.standard_normal((1000, 3))
    rows[7, 1] = np.nan
    path = tmp_path / "blocks.csv"
    with CsvStream(path, ["a", "b", "c"], flush_interval_s=10.0) as stream:  # no flush by the thread
        at = 0
        for b in (1, 255, 2, 300, 99, 1, 0, 342):  # within a block, growing it, past its largest
            stream.write_rows(rows[at:at + b])
            at += b
        assert stream.rows == at == 1000 and np.array_equal(stream.last, rows[-1])
        with pytest.raises(ValueError, match=r"have 3 values; got a block of shape \(2, 4\)"):
            stream.write_rows(np.zeros((2, 4)))
    data = read_csv(path)
    np.testing.assert_array_equal(np.column_stack([data[c] for c in "abc"]), rows)
