"""One-line messages: what the command line prints for an error, whatever the input was.

A message may echo user input (a tag, an expression, a path).  :func:`one_line` escapes
control characters (a newline, a carriage return, an escape sequence from a hostile case
file cannot split the line or drive the terminal) and truncates the message to
:data:`MAX_MESSAGE` characters.  :class:`OneLineParser` makes argparse's errors one line
with a pointer to ``--help`` instead of the usage block.
"""

from __future__ import annotations

import argparse
import sys

#: longest error message printed, in characters
MAX_MESSAGE = 500


def one_line(text: object, limit: int = MAX_MESSAGE) -> str:
    """``text`` on one line: control characters escaped, at most ``limit`` characters."""
    s = str(text)
    if any(ord(c) < 32 or ord(c) == 127 for c in s):
        s = "".join(c if 32 <= ord(c) != 127 else repr(c)[1:-1] for c in s)
    if len(s) > limit:
        s = s[: limit - 30] + f"... ({len(s)} characters in all)"
    return s


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line naming the problem and ``--help``; exit 2."""

    def error(self, message: str):  # noqa: D401 - argparse's interface
        sys.stderr.write(f"signorini: error: {one_line(message)} (see '{self.prog} --help')\n")
        raise SystemExit(2)
