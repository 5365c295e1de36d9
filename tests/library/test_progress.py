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
