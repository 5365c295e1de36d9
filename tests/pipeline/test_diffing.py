"""prodmaps.diffing: per-key numeric tolerances, pixel RMS, side-by-side images, the diff CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from prodmaps.pipeline import cli
from prodmaps.pipeline.diffing import diff_results, diff_runs, flatten, image_rms, tolerance_for

DOC = {
    "parameters": {"profile": "smoke", "out_dir": "results/smoke/x", "ks": [4, 8]},
    "results": {"errors": {"std": {"k4": 0.3242677576577517, "k8": 0.28}, "prod": {"k4": 0.2887}},
                "sizes": {"k4": 21}, "method": "svd", "converged": True, "curve": [0.1, 0.2, 0.3]},
    "prodmaps_version": "0.1.0",
    "versions": {"numpy": "2.4.6", "scipy": "1.17.1"},
}


def _copy(doc):
    return json.loads(json.dumps(doc))


def _img(seed=0, shape=(40, 30)):
    rng = np.random.default_rng(seed)
    return rng.integers(0, 256, size=shape + (3,), dtype=np.uint8)


def make_run(folder: Path, doc=DOC, images=None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "results.json").write_text(json.dumps(doc))
    for name, arr in (images if images is not None else {"fig.png": _img()}).items():
        Image.fromarray(arr).save(folder / name)
    return folder


def test_flatten_dotted_keys():
    f = flatten({"a": {"b": [1, {"c": 2}], "e": {}}, "d": None})
    assert f == {"a.b.0": 1, "a.b.1.c": 2, "a.e": {}, "d": None}


def test_tolerance_longest_glob_wins_and_defaults():
    tol = {"results.*": {"rtol": 1e-2}, "results.errors.std.*": {"rtol": 0.5, "atol": 0.0}}
    assert tolerance_for("results.errors.std.k4", tol)["rtol"] == 0.5
    assert tolerance_for("results.errors.prod.k4", tol)["rtol"] == 1e-2
    t = tolerance_for("parameters.ks.0", tol)
    assert (t["rtol"], t["atol"], t["ignore"]) == (1e-6, 1e-9, False)
    assert tolerance_for("parameters.out_dir", None)["ignore"]
    assert tolerance_for("versions.numpy", None)["ignore"]
    for timing in (
        "results.seconds",
        "results.seconds.per_pair.3",
        "results.render_seconds",
        "results.t.eig_seconds.k9",
    ):
        assert tolerance_for(timing, None)["ignore"], timing
    for value in ("results.errors.k9", "results.secondsless", "results.seconds_note_x"):
        assert not tolerance_for(value, None)["ignore"], value
    with pytest.raises(ValueError, match="unknown keys"):
        tolerance_for("results.x", {"results.*": {"rel": 1}})


def test_identical_results_pass():
    fs = diff_results(_copy(DOC), DOC)
    assert fs and all(f.ok for f in fs)
    assert {f.key for f in fs} >= {"results.errors.std.k4", "results.curve.2", "parameters.ks.1"}
    assert "parameters.out_dir" not in {f.key for f in fs}


@pytest.mark.parametrize("change, key", [
    (lambda d: d["results"]["errors"]["std"].update(k4=0.3242677576577517 * (1 + 1e-5)), "results.errors.std.k4"),
    (lambda d: d["results"]["sizes"].update(k4=22), "results.sizes.k4"),
    (lambda d: d["results"].update(method="lasso"), "results.method"),
    (lambda d: d["results"].update(converged=False), "results.converged"),
    (lambda d: d["results"].update(converged=1), "results.converged"),  # bool vs number
    (lambda d: d["results"]["curve"].pop(), "results.curve.2"),  # missing list element
    (lambda d: d["results"]["errors"]["prod"].update(k8=0.1), "results.errors.prod.k8"),  # extra key
    (lambda d: d["results"]["errors"].pop("prod"), "results.errors.prod.k4"),  # missing key
    (lambda d: d["parameters"].update(ks=[4, 9]), "parameters.ks.1"),
])
def test_each_kind_of_drift_fails_and_names_the_key(change, key):
    new = _copy(DOC)
    change(new)
    bad = [f for f in diff_results(new, DOC) if not f.ok]
    assert [f.key for f in bad] == [key]


def test_within_default_tolerance_passes_and_per_key_tolerance_applies():
    new = _copy(DOC)
    new["results"]["errors"]["std"]["k4"] *= 1 + 5e-7  # within rtol 1e-6
    assert all(f.ok for f in diff_results(new, DOC))
    new["results"]["errors"]["std"]["k4"] = 0.33  # 2% off
    assert not all(f.ok for f in diff_results(new, DOC))
    assert all(f.ok for f in diff_results(new, DOC, {"results.errors.*": {"rtol": 0.05}}))
    assert all(f.ok for f in diff_results(new, DOC, {"results.errors.std.k4": {"ignore": True}}))


def test_version_change_is_a_note_not_a_failure(tmp_path):
    new = _copy(DOC)
    new["versions"]["numpy"] = "9.9.9"
    new["prodmaps_version"] = "0.2.0"
    rep = diff_runs(make_run(tmp_path / "new", new), make_run(tmp_path / "base"))
    assert rep.ok
    assert any("numpy" in n and "9.9.9" in n for n in rep.notes)


def test_image_rms_scale():
    a = np.zeros((4, 4, 3), np.uint8)
    b = a.copy()
    b[0, 0, 0] = 48  # one channel of one pixel: RMS = 48 / sqrt(48) = sqrt(48)
    assert image_rms(a, b) == pytest.approx(np.sqrt(48.0))
    assert image_rms(a, np.full_like(a, 255)) == pytest.approx(255.0)


def test_pngs_small_noise_passes_big_change_fails_with_a_difference_image(tmp_path):
    base = make_run(tmp_path / "base", images={"fig.png": _img(0), "other.png": _img(1)})
    noisy = _img(0).astype(int)
    noisy[::7, ::5] = np.clip(noisy[::7, ::5] + 3, 0, 255)  # a few pixels off by 3: RMS well below 2
    changed = _img(1).copy()
    changed[:10] = 0  # a quarter of the image blacked out
    new = make_run(tmp_path / "new", images={"fig.png": noisy.astype(np.uint8), "other.png": changed})
    rep = diff_runs(new, base)
    assert not rep.ok
    by = {f.key: f for f in rep.findings if f.kind == "image"}
    assert by["fig.png"].ok and by["fig.png"].new < 2.0
    assert not by["other.png"].ok and by["other.png"].new > 2.0
    diff_png = Path(by["other.png"].image)  # matplotlib.testing.compare's difference image
    assert diff_png == tmp_path / "new" / "diff" / "other-failed-diff.png"
    assert Image.open(diff_png).size == (30, 40)
    assert not (tmp_path / "new" / "diff" / "fig-failed-diff.png").exists()
    assert not list((tmp_path / "new").glob("*failed-diff*"))  # nothing written beside the run's images
    md = (tmp_path / "new" / "diff" / "report.md").read_text()
    assert "diff FAIL" in md and "other.png" in md and "pixel RMS" in md


def test_png_size_mismatch_missing_and_extra_fail(tmp_path):
    base = make_run(tmp_path / "base", images={"a.png": _img(0), "gone.png": _img(2)})
    new = make_run(tmp_path / "new", images={"a.png": _img(0, (40, 31)), "extra.png": _img(3)})
    rep = diff_runs(new, base, diff_dir=tmp_path / "dd")
    bad = {f.key: f.detail for f in rep.failures}
    assert set(bad) == {"a.png", "gone.png", "extra.png"}
    assert "size mismatch" in bad["a.png"] and "missing" in bad["gone.png"] and "extra" in bad["extra.png"]
    assert "baseline 30x40, new 31x40" in bad["a.png"]


def test_rgba_png_compared_on_white(tmp_path):
    rgb = np.full((6, 6, 3), 255, np.uint8)
    rgba = np.zeros((6, 6, 4), np.uint8)  # fully transparent == white background
    base = make_run(tmp_path / "base", images={"x.png": rgb})
    (tmp_path / "new").mkdir()
    (tmp_path / "new" / "results.json").write_text(json.dumps(DOC))
    Image.fromarray(rgba, "RGBA").save(tmp_path / "new" / "x.png")
    assert diff_runs(tmp_path / "new", base).ok


def test_missing_results_json_and_missing_baseline(tmp_path):
    base = make_run(tmp_path / "base")
    new = tmp_path / "new"
    new.mkdir()
    Image.fromarray(_img()).save(new / "fig.png")
    rep = diff_runs(new, base)
    assert [f.detail for f in rep.failures] == ["no results.json in the run folder"]
    with pytest.raises(FileNotFoundError, match="update-baselines"):
        diff_runs(new, tmp_path / "nothing")


def test_cli_diff_uses_registry_tolerances(tmp_path, monkeypatch, capsys):
    reg = tmp_path / "runs.toml"
    reg.write_text('root = "."\n[runs.fig99]\nnotebook = "x.ipynb"\n'
                   '[runs.fig99.tolerances]\n"results.errors.*" = { rtol = 0.05, atol = 0.0 }\n')
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    base = make_run(tmp_path / "baselines" / "fig99")
    new_doc = _copy(DOC)
    new_doc["results"]["errors"]["std"]["k8"] = 0.285  # 1.8% drift: allowed for fig99 only
    new = make_run(tmp_path / "new", new_doc)
    assert cli.main(["diff", str(new), str(base)]) == 0
    assert "diff PASS" in capsys.readouterr().out
    other = make_run(tmp_path / "baselines" / "other")
    assert cli.main(["diff", str(new), str(other)]) == 1
    out = capsys.readouterr().out
    assert "diff FAIL" in out and "results.errors.std.k8" in out
    assert cli.main(["diff", str(new), str(other), "--run", "fig99"]) == 0
    assert cli.main(["diff", str(new), str(tmp_path / "none")]) == 2


def test_cli_diff_two_profile_folders_and_refuses_two_different_runs(tmp_path, monkeypatch, capsys):
    reg = tmp_path / "runs.toml"
    reg.write_text('root = "."\n[runs.fig98]\nnotebook = "x.ipynb"\n[runs.fig99]\nnotebook = "y.ipynb"\n')
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    for prof in ("new", "base"):
        for run in ("fig98", "fig99"):
            make_run(tmp_path / prof / run)
    assert cli.main(["diff", str(tmp_path / "new"), str(tmp_path / "base")]) == 0
    out = capsys.readouterr().out
    assert out.count("diff PASS") == 2 and "2 run(s) compared" in out
    drift = _copy(DOC)
    drift["results"]["errors"]["std"]["k8"] = 0.5
    make_run(tmp_path / "new" / "fig99", drift)
    assert cli.main(["diff", str(tmp_path / "new"), str(tmp_path / "base")]) == 1
    capsys.readouterr()
    assert cli.main(["diff", str(tmp_path / "new" / "fig98"), str(tmp_path / "base" / "fig99")]) == 2
    assert "another run" in capsys.readouterr().err


def test_cli_diff_of_two_profile_folders_fails_on_a_run_missing_from_the_new_one(tmp_path, monkeypatch, capsys):
    reg = tmp_path / "runs.toml"
    reg.write_text('root = "."\n[runs.fig98]\nnotebook = "x.ipynb"\n[runs.fig99]\nnotebook = "y.ipynb"\n')
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    for run in ("fig98", "fig99"):
        make_run(tmp_path / "base" / run)
    make_run(tmp_path / "new" / "fig98")  # fig99 did not run (or wrote no results.json)
    assert cli.main(["diff", str(tmp_path / "new"), str(tmp_path / "base")]) == 1
    out = capsys.readouterr().out
    assert "1 run(s) compared" in out and "['fig99']" in out and "in the baseline only" in out
    assert cli.main(["diff", str(tmp_path / "new" / "fig98"), str(tmp_path / "base" / "fig98")]) == 0


def test_cli_diff_refuses_a_registry_it_cannot_read_instead_of_dropping_its_tolerances(tmp_path, monkeypatch,
                                                                                        capsys):
    monkeypatch.delenv("PRODMAPS_RUNS", raising=False)
    base, new = make_run(tmp_path / "base" / "fig99"), make_run(tmp_path / "new" / "fig99")
    assert cli.main(["diff", str(new), str(base), "--registry", str(tmp_path / "nope.toml")]) == 2
    assert "nope.toml" in capsys.readouterr().err
    monkeypatch.setenv("PRODMAPS_RUNS", str(tmp_path / "nope.toml"))
    assert cli.main(["diff", str(new), str(base)]) == 2
    monkeypatch.delenv("PRODMAPS_RUNS")
    monkeypatch.chdir(tmp_path)  # no paper/runs.toml here or above: the defaults, said so
    assert cli.main(["diff", str(new), str(base)]) == 0
    assert "default tolerances" in capsys.readouterr().err


@pytest.mark.parametrize("value", ["-1", "nan", "abc", "300"])
def test_cli_diff_refuses_a_png_threshold_outside_0_255(tmp_path, capsys, value):
    base, new = make_run(tmp_path / "base" / "fig99"), make_run(tmp_path / "new" / "fig99")
    with pytest.raises(SystemExit) as exc:
        cli.main(["diff", str(new), str(base), "--png-threshold", value])
    assert exc.value.code == 2 and "--png-threshold" in capsys.readouterr().err


def test_cli_diff_pairs_a_profile_folder_with_one_run_folder_either_way(tmp_path, monkeypatch, capsys):
    # `prodmaps diff results/smoke paper/baselines/smoke/fig02`: the run fig02 of the profile folder
    reg = tmp_path / "runs.toml"
    reg.write_text('root = "."\n[runs.fig98]\nnotebook = "x.ipynb"\n[runs.fig99]\nnotebook = "y.ipynb"\n'
                   '[runs.fig99.tolerances]\n"results.errors.*" = { rtol = 0.05, atol = 0.0 }\n')
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    for run in ("fig98", "fig99"):
        make_run(tmp_path / "base" / run)
    drift = _copy(DOC)
    drift["results"]["errors"]["std"]["k8"] = 0.285  # within fig99's tolerance only
    make_run(tmp_path / "new" / "fig99", drift)
    new, base = tmp_path / "new", tmp_path / "base"
    assert cli.main(["diff", str(new), str(base / "fig99")]) == 0  # fig99's own tolerances applied
    cap = capsys.readouterr()
    assert cap.out.count("diff PASS") == 1 and f"`{new / 'fig99'}` vs baseline `{base / 'fig99'}`" in cap.out
    assert f"comparing the run folder {new / 'fig99'} with {base / 'fig99'}" in cap.err
    assert cli.main(["diff", str(new / "fig99"), str(base)]) == 0  # the other way round
    assert f"vs baseline `{base / 'fig99'}`" in capsys.readouterr().out
    assert cli.main(["diff", str(new), str(base), "--run", "fig99"]) == 0  # two profile folders, one run
    assert capsys.readouterr().out.count("diff PASS") == 1
    make_run(tmp_path / "new" / "fig98", drift)  # fig98 keeps the default tolerance: the same drift fails
    assert cli.main(["diff", str(new), str(base / "fig98")]) == 1
    assert "results.errors.std.k8" in capsys.readouterr().out
    # a run the profile folder does not hold: refused, saying what it holds and what to pass
    make_run(tmp_path / "base" / "fig97")
    assert cli.main(["diff", str(new), str(base / "fig97")]) == 2
    err = capsys.readouterr().err
    assert "without the run 'fig97'" in err and "fig98, fig99" in err and "pass two run folders" in err
