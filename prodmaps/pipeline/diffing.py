"""Compare a run's outputs with a baseline: numbers with per-key tolerances, PNGs by pixel RMS.

``diff_runs(run_dir, baseline_dir, tolerances)`` compares

* ``results.json`` key by key. Nested dicts and lists are flattened to dotted keys from the
  document root (``results.errors.std.k9``, ``results.curve.3``). Numbers pass when
  ``|new - base| <= atol + rtol * |base|`` (default ``rtol = 1e-6``, ``atol = 1e-9``); strings,
  booleans and nulls must be equal; a key present on one side only is a failure.
  ``tolerances`` maps dotted-key globs (:mod:`fnmatch`, ``*`` also crosses dots) to
  ``{"rtol": .., "atol": ..}`` or ``{"ignore": true}``; the longest matching glob wins.
  Ignored by default: ``parameters.out_dir`` (where the run wrote), ``prodmaps_version``,
  ``versions.*`` (version differences are listed as notes, not failures) and wall times:
  any key named ``seconds`` or ending in ``_seconds`` (with everything below it) — notebook
  authors, name timings that way.
* every ``*.png`` at the top level of both folders by the RMS of the pixel difference over all
  channels (0-255 scale, default threshold 2.0), computed and illustrated by matplotlib's own
  image comparison (``matplotlib.testing.compare``: ``calculate_rms``, and the
  ``*-failed-diff.png`` difference image of ``compare_images`` for each failing image, written
  into the diff folder, default ``<run_dir>/diff/``, together with ``report.md``). A size
  mismatch or a PNG present on one side only is a failure.

matplotlib and Pillow are imported inside the image functions.
"""

from __future__ import annotations

import fnmatch
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..experiments.shared.results import flatten

__all__ = ["DEFAULT_RTOL", "DEFAULT_ATOL", "DEFAULT_PNG_THRESHOLD", "DEFAULT_IGNORE", "Finding",
           "DiffReport", "diff_runs", "diff_results", "diff_images", "flatten", "tolerance_for",
           "image_rms"]

DEFAULT_RTOL = 1e-6
DEFAULT_ATOL = 1e-9
DEFAULT_PNG_THRESHOLD = 2.0
DEFAULT_IGNORE = ("parameters.out_dir", "prodmaps_version", "versions", "versions.*",
                  # wall times are never reproducible: keys named `seconds` or ending in `_seconds`
                  "*.seconds", "*.seconds.*", "*_seconds", "*_seconds.*")


@dataclass
class Finding:
    """One compared item. ``kind`` is ``"number"``, ``"value"``, ``"key"`` or ``"image"``."""

    kind: str
    key: str
    ok: bool
    baseline: object = None
    new: object = None
    detail: str = ""
    image: str = ""  # diff image path (failing images)


@dataclass
class DiffReport:
    """What a run's diff against its baseline found: the values' and images' findings and notes."""

    run_dir: str
    baseline_dir: str
    findings: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    diff_dir: str = ""

    @property
    def failures(self) -> list:
        """The findings outside their tolerance."""
        return [f for f in self.findings if not f.ok]

    @property
    def ok(self) -> bool:
        """True when no finding failed."""
        return not self.failures

    def counts(self) -> dict:
        """Values and images compared and failed: ``values``, ``values_failed``, ``images``, ``images_failed``."""
        nums = [f for f in self.findings if f.kind != "image"]
        imgs = [f for f in self.findings if f.kind == "image"]
        return {"values": len(nums), "values_failed": sum(not f.ok for f in nums),
                "images": len(imgs), "images_failed": sum(not f.ok for f in imgs)}

    def to_markdown(self, max_rows: int = 50) -> str:
        """The report as Markdown: counts, then at most ``max_rows`` drifted values, images and notes."""
        c = self.counts()
        verdict = "PASS" if self.ok else "FAIL"
        lines = [f"## diff {verdict}: `{self.run_dir}` vs baseline `{self.baseline_dir}`", "",
                 f"{c['values']} values compared, {c['values_failed']} drifted; "
                 f"{c['images']} images compared, {c['images_failed']} drifted.", ""]
        bad = [f for f in self.failures if f.kind != "image"]
        if bad:
            lines += ["| key | baseline | new | detail |", "|---|---|---|---|"]
            lines += [f"| `{f.key}` | {_fmt(f.baseline)} | {_fmt(f.new)} | {f.detail} |" for f in bad[:max_rows]]
            if len(bad) > max_rows:
                lines.append(f"| ... {len(bad) - max_rows} more | | | |")
            lines.append("")
        bad = [f for f in self.failures if f.kind == "image"]
        if bad:
            lines += ["| image | detail | side by side |", "|---|---|---|"]
            lines += [f"| `{f.key}` | {f.detail} | {f'`{f.image}`' if f.image else ''} |" for f in bad] + [""]
        lines += [f"- note: {n}" for n in self.notes]
        return "\n".join(lines).rstrip() + "\n"

    def __str__(self) -> str:
        return self.to_markdown()


def _fmt(v) -> str:
    if v is None:
        return "(missing)"
    if isinstance(v, float):
        return f"{v:.10g}"
    s = json.dumps(v) if not isinstance(v, str) else repr(v)
    return s if len(s) < 60 else s[:57] + "..."


_MISSING = object()


def tolerance_for(key: str, tolerances: dict | None) -> dict:
    """``{"rtol", "atol", "ignore"}`` for ``key``: the longest matching glob, else the defaults."""
    tol = {"rtol": DEFAULT_RTOL, "atol": DEFAULT_ATOL, "ignore": False}
    globs = {g: {"ignore": True} for g in DEFAULT_IGNORE}
    globs.update(tolerances or {})
    best = max((g for g in globs if fnmatch.fnmatchcase(key, g)), key=len, default=None)
    if best is not None:
        spec = globs[best]
        if not isinstance(spec, dict):
            raise ValueError(f"tolerance for {best!r} must be a table like {{rtol = 1e-6, atol = 1e-9}}")
        unknown = set(spec) - {"rtol", "atol", "ignore"}
        if unknown:
            raise ValueError(f"tolerance for {best!r}: unknown keys {sorted(unknown)} (use rtol, atol, ignore)")
        tol.update({k: spec[k] for k in spec})
    return tol


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def diff_results(new: dict, base: dict, tolerances: dict | None = None) -> list[Finding]:
    """Compare two results documents (already parsed) key by key."""
    fn, fb = flatten(new), flatten(base)
    findings = []
    for key in list(fb) + [k for k in fn if k not in fb]:
        tol = tolerance_for(key, tolerances)
        if tol["ignore"]:
            continue
        b, n = fb.get(key, _MISSING), fn.get(key, _MISSING)
        if b is _MISSING:
            findings.append(Finding("key", key, False, None, n, "extra key (not in the baseline)"))
        elif n is _MISSING:
            findings.append(Finding("key", key, False, b, None, "missing key (in the baseline only)"))
        elif _is_number(b) and _is_number(n):
            d = abs(float(n) - float(b))
            allowed = float(tol["atol"]) + float(tol["rtol"]) * abs(float(b))
            ok = d <= allowed and math.isfinite(float(n)) == math.isfinite(float(b))
            findings.append(Finding("number", key, ok, b, n,
                                    f"|diff| {d:.3g} {'<=' if ok else '>'} {allowed:.3g} "
                                    f"(rtol {tol['rtol']:g}, atol {tol['atol']:g})"))
        else:
            ok = type(b) is type(n) and b == n
            findings.append(Finding("value", key, ok, b, n, "" if ok else "values differ"))
    return findings


def image_rms(a, b) -> float:
    """RMS of two equal-sized uint8 images' difference (0-255), as ``matplotlib.testing.compare.calculate_rms``."""
    from matplotlib.testing.compare import calculate_rms

    return float(calculate_rms(np.asarray(a, dtype=np.int16), np.asarray(b, dtype=np.int16)))


def _load(path: Path) -> "np.ndarray":
    """An image as RGB uint8; transparency is composited on white (the figures' background)."""
    from PIL import Image

    with Image.open(path) as im:
        if im.mode in ("RGBA", "LA", "P"):
            im = im.convert("RGBA")
            im = Image.alpha_composite(Image.new("RGBA", im.size, (255, 255, 255, 255)), im)
        return np.asarray(im.convert("RGB"), dtype=np.uint8)


def diff_images(run_dir, baseline_dir, *, threshold: float = DEFAULT_PNG_THRESHOLD,
                diff_dir=None) -> list[Finding]:
    """Compare the top-level PNGs of two folders by pixel RMS (``matplotlib.testing.compare``).

    For every image beyond ``threshold`` the difference image of ``compare_images``
    (``<name>-failed-diff.png``) is written into ``diff_dir``.
    """
    import shutil
    import tempfile

    from matplotlib.testing.compare import compare_images

    run_dir, baseline_dir = Path(run_dir), Path(baseline_dir)
    diff_dir = Path(diff_dir) if diff_dir is not None else run_dir / "diff"
    new = {p.name for p in run_dir.glob("*.png")}
    base = {p.name for p in baseline_dir.glob("*.png")}
    findings = []
    for name in sorted(base | new):
        if name not in new or name not in base:
            findings.append(Finding("image", name, False, detail="missing image (in the baseline only)"
                                    if name not in new else "extra image (not in the baseline)"))
            continue
        a, b = _load(baseline_dir / name), _load(run_dir / name)
        if a.shape != b.shape:
            findings.append(Finding("image", name, False, a.shape[:2], b.shape[:2],
                                    f"size mismatch: baseline {a.shape[1]}x{a.shape[0]}, "
                                    f"new {b.shape[1]}x{b.shape[0]}"))
            continue
        rms = image_rms(a, b)
        ok = rms <= threshold
        out = ""
        if not ok:  # matplotlib writes <actual>-failed-diff.png beside the actual image: do it in a scratch copy
            with tempfile.TemporaryDirectory() as tmp:
                actual = Path(tmp) / name
                shutil.copyfile(run_dir / name, actual)
                res = compare_images(str(baseline_dir / name), str(actual), tol=threshold, in_decorator=True)
                if res:
                    diff_dir.mkdir(parents=True, exist_ok=True)
                    out = str(diff_dir / Path(res["diff"]).name)
                    shutil.move(res["diff"], out)
        findings.append(Finding("image", name, ok, None, rms,
                                f"pixel RMS {rms:.3f} {'<=' if ok else '>'} {threshold:g}", out))
    return findings


def diff_runs(run_dir, baseline_dir, tolerances: dict | None = None, *,
              png_threshold: float = DEFAULT_PNG_THRESHOLD, diff_dir=None,
              write_report: bool = True) -> DiffReport:
    """Compare ``run_dir`` with ``baseline_dir`` (see the module doc); returns a :class:`DiffReport`.

    ``report.ok`` is False on any failure of the module doc (``png_threshold``: the pixel RMS
    threshold); the difference images and ``report.md`` then go into ``diff_dir`` (default
    ``<run_dir>/diff``).
    """
    run_dir, baseline_dir = Path(run_dir), Path(baseline_dir)
    if not baseline_dir.is_dir():
        raise FileNotFoundError(
            f"baseline folder {baseline_dir} does not exist; create it deliberately with "
            "`prodmaps reproduce --profile smoke --update-baselines --only RUN`")
    if not run_dir.is_dir():
        raise FileNotFoundError(f"run folder {run_dir} does not exist")
    diff_dir = Path(diff_dir) if diff_dir is not None else run_dir / "diff"
    rep = DiffReport(str(run_dir), str(baseline_dir), diff_dir=str(diff_dir))
    rn, rb = run_dir / "results.json", baseline_dir / "results.json"
    if rn.is_file() and rb.is_file():
        new, base = json.loads(rn.read_text()), json.loads(rb.read_text())
        rep.findings += diff_results(new, base, tolerances)
        vn, vb = flatten(new.get("versions", {})), flatten(base.get("versions", {}))
        rep.notes += [f"version of {k}: baseline {vb.get(k)}, new {vn.get(k)}" for k in sorted(set(vn) | set(vb))
                      if vn.get(k) != vb.get(k)]
    else:
        rep.findings += [Finding("key", "results.json", False, detail=f"no results.json in the {side} folder")
                         for p, side in ((rb, "baseline"), (rn, "run")) if not p.is_file()]
    rep.findings += diff_images(run_dir, baseline_dir, threshold=png_threshold, diff_dir=diff_dir)
    if write_report and not rep.ok:
        diff_dir.mkdir(parents=True, exist_ok=True)
        (diff_dir / "report.md").write_text(rep.to_markdown())
    return rep
