"""MkDocs hooks: the reference pages' generated parts, made from the code as the site is built.

A page asks for one with a line of its own, `<!-- generated: NAME -->`; the line is replaced by what the
generator of that name returns. On GitHub the line is an invisible comment, and the page says where the same
text comes from on the command line.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))  # MkDocs loads a hook by its path, not as a package

from cli_reference import cli_reference
from spec_reference import spec_reference

GENERATORS = {"spec-reference": spec_reference, "cli-reference": cli_reference}
MARKER = re.compile(r"^<!-- generated: ([a-z-]+) -->$", re.M)


def on_page_markdown(markdown: str, page: Any, **_: Any) -> str:
    def generate(match: re.Match[str]) -> str:
        name = match.group(1)
        if name not in GENERATORS:
            raise SystemExit(f"{page.file.src_path}: no generator named {name!r} (known: {', '.join(GENERATORS)})")
        return GENERATORS[name]()

    return MARKER.sub(generate, markdown)
