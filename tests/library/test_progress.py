import io

from prodmaps.progress import NullBar, progress_bar, wants_progress


class _Tty(io.StringIO):
    def isatty(self):
        return True


def test_default_shows_only_long_work_on_a_terminal():
    assert not wants_progress(None, work=1e12, min_work=1e9, stream=io.StringIO())  # not a terminal
    assert not wants_progress(None, work=1e6, min_work=1e9, stream=_Tty())  # short
    assert wants_progress(None, work=1e12, min_work=1e9, stream=_Tty())
    assert wants_progress(True, stream=io.StringIO()) and not wants_progress(False, work=1e30, stream=_Tty())


def test_bar_writes_its_steps_and_a_silent_bar_writes_nothing():
    out = io.StringIO()
    bar = progress_bar(4, "convert", progress=True, stream=out, unit="block")
    for _ in range(4):
        bar.update(1)
    bar.close()
    text = out.getvalue()
    assert "convert" in text and "4/4" in text
    quiet = io.StringIO()
    bar = progress_bar(4, "convert", stream=quiet)  # default, not a terminal
    assert isinstance(bar, NullBar)
    bar.update(2)
    assert bar.n == 2 and quiet.getvalue() == ""


def test_an_unknown_total_counts_without_an_end(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "tqdm", None)  # the plain-lines fallback
    out = io.StringIO()
    bar = progress_bar(None, "NO17", progress=True, stream=out, unit="iteration")
    bar.update(1)
    bar.update(1)
    assert out.getvalue().splitlines() == ["NO17: iteration 1", "NO17: iteration 2"]


def test_eigenbases_and_no17_show_progress_when_asked_and_stay_silent_by_default(capfd):
    import numpy as np

    import prodmaps as pm
    from prodmaps.fmaps import fit_no17

    m1, m2 = pm.mesh.ellipsoid(2), pm.mesh.ellipsoid(2, axes=(1.1, 0.6, 0.35))
    b = pm.eigenbasis(m1, 10, progress=True)
    err = capfd.readouterr().err
    assert "eigenbasis ellipsoid" in err and "2/2" in err
    quiet = pm.eigenbasis(m1, 10)  # default: not a terminal (and small), silent
    assert capfd.readouterr().err == ""
    np.testing.assert_array_equal(quiet.vecs, b.vecs)  # the bar changes nothing
    bs = pm.basis.eigenbases([m1, pm.PointCloud(m2.vertices)], 10, jobs=1, progress=True)
    err = capfd.readouterr().err
    assert "eigenbases" in err and "2/2" in err and bs[1].kind == "point_cloud"
    b2 = pm.eigenbasis(m2, 10)
    d1, d2 = b.vecs[:, 1:4] ** 2, b2.vecs[:, 1:4] ** 2
    C, info = fit_no17(b, b2, d1, d2, progress=True, return_info=True)
    err = capfd.readouterr().err
    assert "NO17" in err and f"{info['nit']}" in err  # one step per L-BFGS iteration
    np.testing.assert_array_equal(fit_no17(b, b2, d1, d2), C)
    assert capfd.readouterr().err == ""
