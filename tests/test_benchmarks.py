"""The benchmark scripts load as programs, and the streaming probe sums what it reads.

Benchmarks time and report, so they are not run here; but a script that no longer imports
(a module it reads moved) should fail a test, not the next person who runs it.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"
SCRIPTS = sorted(p.stem for p in BENCHMARKS.glob("*.py"))


def test_every_benchmark_script_imports_as_a_program_would_load_it():
    # as `python benchmarks/x.py` loads it (its folder first on sys.path), without running its main;
    # one fresh process for all, the failures reported by name
    code = ("import importlib, json, sys, traceback\n"
            f"sys.path.insert(0, {str(BENCHMARKS)!r})\n"
            "failed = {}\n"
            f"for name in {SCRIPTS!r}:\n"
            "    try:\n"
            "        importlib.import_module(name)\n"
            "    except Exception:\n"
            "        failed[name] = traceback.format_exc(limit=2)\n"
            "print(json.dumps(failed))\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=BENCHMARKS.parent)
    assert p.returncode == 0, p.stderr[-2000:]
    failed = json.loads(p.stdout.strip().splitlines()[-1])
    assert not failed, failed
    assert {"history_law", "history_law_baseline", "streaming", "speed"} <= set(SCRIPTS)


@pytest.fixture(scope="module")
def streaming():
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import streaming
    finally:
        sys.path.remove(str(BENCHMARKS))
    return streaming


@pytest.mark.parametrize("size", [0, 1, 63, 64, 65, 10_001])
def test_every_form_of_the_probe_reads_every_value_once(streaming, size):
    a = np.arange(size, dtype=float)  # sum n (n - 1) / 2: exact in float64 at these sizes
    expected = size * (size - 1) / 2
    for probe in (streaming.stream, streaming.stream_fastmath, streaming.stream_one_thread):
        assert probe(a) == expected
