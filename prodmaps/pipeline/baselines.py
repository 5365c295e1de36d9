"""Smoke baselines: the committed ``results.json`` and PNGs each run is diffed against in CI."""

from __future__ import annotations

import shutil
from pathlib import Path

from .execute import RunResult, mkdtemp_beside, swap_into_place
from .registry import registry_path

__all__ = ["baselines_dir", "update_baselines"]


def baselines_dir(registry=None, profile: str = "smoke") -> Path:
    """``<folder of the registry>/baselines/<profile>`` (``paper/baselines/smoke`` by default)."""
    return registry_path(registry).parent / "baselines" / profile


def update_baselines(results: list[RunResult], dest) -> list[str]:
    """Copy ``results.json`` and PNGs of successful runs into ``dest/<run>/`` (replacing it)."""
    dest = Path(dest)
    done = []
    for r in results:
        if r.status not in ("ok", "skipped"):
            continue
        src = Path(r.run_dir)
        dest.mkdir(parents=True, exist_ok=True)
        tmp = mkdtemp_beside(dest / r.name, r.name)
        for f in [src / "results.json", *sorted(src.glob("*.png"))]:
            shutil.copy2(f, tmp / f.name)
        swap_into_place(tmp, dest / r.name)
        done.append(r.name)
    return done

