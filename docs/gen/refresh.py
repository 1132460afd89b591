"""`make docs-snippets`: run every page's examples and write their real output and figures into the pages.

Each page's captured output blocks (`<!-- output -->` before a ```console block) get what their commands print now,
and its figures (`<!--fig NAME-->...<!--/fig-->`) the values docs/gen/figures.py computes. Nothing else in a page
changes. tests/test_docs.py fails while a page is not what this would write. A command that exits otherwise than its
comment says stops the refresh, naming the page and line.

    python docs/gen/refresh.py [PAGE...]    # default: README.md and every page under docs/
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from figures import evaluate
from runnable import ROOT, Workdir, extract, figures_in, pages, rewrite_captures, rewrite_figures


def refresh(page: Path, scratch: Path) -> bool:
    """Rewrite one page; whether it changed."""
    text = page.read_text(encoding="utf-8")
    name = page.relative_to(ROOT).as_posix()
    examples = extract(text, name)
    captured = [e for e in examples if e.capture is not None]
    figures = {fig for fig, _ in figures_in(text)}
    if not captured and not figures:
        return False
    workdir = Workdir.make(scratch / name.replace("/", "_"))
    outputs: dict[int, list[str]] = {}
    last = max((e.line for e in captured), default=0)
    for example in examples:
        if example.line > last:
            break  # what comes after the last captured block changes nothing written
        proc = workdir.run(example)
        if proc.returncode != example.exit_code:
            raise SystemExit(
                f"{name}:{example.line}: exits {proc.returncode}, not {example.exit_code}: {example.text}\n"
                f"{proc.stdout[-3000:]}"
            )
        if example.capture is not None:
            outputs[example.line] = example.capture.select(proc.stdout)
    new = rewrite_captures(text, outputs, examples)
    if figures:
        new = rewrite_figures(new, evaluate(figures, workdir))
    if new != text:
        page.write_text(new, encoding="utf-8")
        return True
    return False


def main(argv: list[str]) -> int:
    chosen = [Path(a).resolve() for a in argv] or pages()
    with tempfile.TemporaryDirectory(prefix="netcfg-docs-") as scratch:
        for page in chosen:
            changed = refresh(page, Path(scratch))
            print(f"{page.relative_to(ROOT)}: {'rewritten' if changed else 'current'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
