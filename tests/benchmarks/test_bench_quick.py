"""`make bench` in its quick mode: tiny sizes, the same code paths and the same equality checks.

The benchmarks assert that every fast route gives its baseline's answer (the Approach B operator
against a direct SVD in the same reading, batched against one-by-one transfer, the default
transfer never worse than the standard one); this runs them in seconds so a change that breaks
them fails the test suite, not only `make bench`.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_quick_benchmarks_run_and_their_answers_agree(tmp_path):
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "run.py"), "--quick", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    doc = json.loads((tmp_path / "bench.json").read_text())
    assert doc["quick"] is True
    rows = {row["name"]: row for row in doc["benchmarks"]}
    assert {"approach_b", "transfer", "default", "scale_1m"} <= set(rows)
    assert "unit-Euclidean" in rows["approach_b"]["baseline"] and "coefficients equal to" in rows["approach_b"]["check"]
    assert rows["approach_b"]["floor_s"] > 0 and "floor" in rows["approach_b"]["check"]
    # the million-vertex script's code paths at 5k vertices: the Cholesky eigensolver, the approximate
    # search of the full point map, its recall and geodesic error against the exact conversion
    scale = rows["scale_1m"]
    assert "cholesky" in scale["what"] and "approximate search" in scale["what"]
    assert "recall" in scale["check"] and "mean geodesic error" in scale["check"]
    assert (tmp_path / "bench.md").is_file()
