"""Exit codes of the command line (one source for every command)."""

from __future__ import annotations

EXIT_CODES = {"finished": 0, "failed": 3, "interrupted": 130}


EXIT_ENVIRONMENT = 4
