"""``mbctl --cpus``: the cores parsed and checked, the process and its later threads pinned, the report."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mbctl.jobs.cpus import CpuSetError, available_cpus, parse_cpus, pin_process
from tests.conftest import run_mbctl

needs_affinity = pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="an OS without affinities")


@given(st.lists(st.tuples(st.integers(0, 200), st.integers(0, 5)), min_size=1, max_size=6))
def test_a_list_of_cores_and_ranges_parses_to_their_union(parts):
    text = ", ".join(f"{lo}-{lo + n}" if n else str(lo) for lo, n in parts)
    assert parse_cpus(text) == {c for lo, n in parts for c in range(lo, lo + n + 1)}


@pytest.mark.parametrize(("text", "message"), [
    ("", "'' is not a core number or a range A-B"),
    ("0,,1", "'' is not a core number or a range A-B"),
    ("a", "'a' is not a core number or a range A-B"),
    ("1.5", "'1.5' is not a core number or a range A-B"),
    ("0-", "'0-' is not a core number or a range A-B"),
    ("3-1", "'3-1' is not a range of cores from 0 up"),
    ("-1", "'-1' is not a core number or a range A-B"),
])
def test_a_malformed_core_list_names_the_bad_part_and_the_form(text, message):
    with pytest.raises(CpuSetError) as err:
        parse_cpus(text)
    assert str(err.value) == (f"--cpus {text!r}: {message}; expected core numbers and ranges, e.g. 0 or 0,2 "
                              "or 1-3")


@needs_affinity
def test_a_core_the_process_may_not_use_is_refused_with_the_ones_it_may(monkeypatch):
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1})
    monkeypatch.setattr(os, "sched_setaffinity", lambda pid, cores: pytest.fail("pinned to a core it lacks"))
    with pytest.raises(CpuSetError, match=r"^--cpus '1-3': core\(s\) 2, 3 not available to this process; "
                                          r"it may use 0, 1$"):
        pin_process("1-3")


@needs_affinity
def test_pinning_holds_for_the_process_and_every_thread_it_starts_later():
    # in a child process: pinning this test process would pin the rest of the session
    last = max(available_cpus())
    code = ("import os, threading\n"
            "from mbctl.jobs.cpus import pin_process\n"
            f"print(pin_process('{last}'))\n"
            "seen = []\n"
            "t = threading.Thread(target=lambda: seen.append(sorted(os.sched_getaffinity(0))))\n"
            "t.start(); t.join()\n"
            "print(sorted(os.sched_getaffinity(0)), seen[0])\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split("\n")[:2] == [f"({last},)", f"[{last}] [{last}]"]


@needs_affinity
def test_the_cli_runs_a_job_on_the_cores_given_and_its_report_says_so(tmp_path):
    last = max(available_cpus())
    out = run_mbctl("--cpus", str(last), "workspace", "--samples", "11", "--output", str(tmp_path / "ws"))
    assert out.returncode == 0, out.stderr
    report = json.loads((tmp_path / "ws" / "report.json").read_text())
    assert report["environment"]["cpus"] == [last]
    unpinned = run_mbctl("workspace", "--samples", "11", "--output", str(tmp_path / "ws2"))
    assert json.loads((tmp_path / "ws2" / "report.json").read_text())["environment"]["cpus"] == sorted(
        available_cpus())
    assert unpinned.returncode == 0


def test_the_cli_refuses_a_bad_core_list_with_exit_2_and_no_traceback(tmp_path):
    out = run_mbctl("--cpus", "4096", "workspace", "--output", str(tmp_path / "ws"))
    assert out.returncode == 2
    assert out.stderr.startswith("error: --cpus '4096': core(s) 4096 not available to this process; "
                                 "it may use ")
    assert "Traceback" not in out.stderr and not (tmp_path / "ws").exists()
