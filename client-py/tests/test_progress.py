"""The applications' progress bars draw on a terminal only: into a pipe, a file or a CI
log they write nothing (no carriage returns, no escape codes)."""

from __future__ import annotations

import io

from echogym._progress import progress_bar


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _draw(file: io.StringIO, enabled: bool = True) -> str:
    bar = progress_bar(50, enabled=enabled, file=file, unit="step", mininterval=0)
    for _ in range(50):
        bar.update(1)
        bar.set_postfix_str("123 env-steps/s")
    bar.close()
    return file.getvalue()


def test_a_pipe_gets_nothing():
    assert _draw(io.StringIO()) == ""


def test_a_terminal_gets_the_bar_unless_disabled():
    drawn = _draw(Terminal())
    assert "\r" in drawn and "50/50" in drawn
    assert _draw(Terminal(), enabled=False) == ""
