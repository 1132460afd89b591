"""Every command and Python example of the README and the documentation site runs as shown.

The pages are read, not copied (docs/gen/runnable.py says how): a command line starting with `netcfg ` or `python `
in a fenced or indented block runs through the shell with the exit code its comment gives, every ```python block
runs as a program, a titled block is a file written before the commands after it, and the output a page shows is
output the command prints. Each page runs in a working folder of its own, so `netcfg build` writes into a copy,
never into the checkout. A line or block that cannot run in CI says so visibly, with `not run in CI` and the reason
beside it in its comment; that is the only way out.

Captured output blocks and figures in prose are written by `make docs-snippets`; here they must be what the commands
print now, so a page cannot quote a figure the code no longer gives.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT

sys.path.insert(0, str(ROOT / "docs" / "gen"))

from figures import FIGURES, evaluate
from runnable import (
    Example,
    Workdir,
    capture_differences,
    extract,
    figures_in,
    missing_output,
    page_examples,
    pages,
)

EXAMPLES = list(page_examples())
README_LINES = 200


def test_the_extractor_finds_fenced_indented_titled_captured_and_opted_out_blocks() -> None:
    """A hand-written Markdown text: what must be picked up and what must not."""
    text = "\n".join([
        "Intro `netcfg inline` is prose.",
        "",
        "    netcfg check a.yaml        # a comment",
        "    netcfg/spec/ is a folder, not a command",
        "    python x.py --flag     # exits 1: on purpose",
        "",
        "```",
        "$ netcfg build a.yaml",
        "netcfg run a.yaml --interface socketcan   # not run in CI: needs a CAN adapter",
        "```",
        "",
        "```python",
        "print('hi')",
        "```",
        "",
        "```python",
        "bus = can.Bus('can0')  # not run in CI: real hardware",
        "```",
        "",
        "```yaml",
        "netcfg check inside yaml is data",
        "```",
        "",
        '```yaml title="b.yaml"',
        "system: b",
        "```",
        "",
        "<!-- output: head=1 -->",
        "```console",
        "$ netcfg check b.yaml  # exits 1: b has no bus",
        "netcfg check is named in the output, not run",
        "",
        "```",
    ])
    got = [(e.line, e.kind, e.text, e.exit_code) for e in extract(text)]
    assert got == [
        (3, "shell", "netcfg check a.yaml", 0),
        (5, "shell", "python x.py --flag", 1),
        (8, "shell", "netcfg build a.yaml", 0),
        (13, "python", "print('hi')\n", 0),
        (25, "file", "system: b\n", 0),
        (30, "shell", "netcfg check b.yaml", 1),
    ]
    captured = extract(text)[-1]
    assert captured.shown == ("netcfg check is named in the output, not run",)
    assert captured.capture is not None and captured.capture.head == 1


def test_a_capture_selects_and_masks_as_its_options_say() -> None:
    from runnable import Capture

    printed = "a 1\nb 2\nc 3\nd 4\n"
    assert Capture.parse("head=1 tail=1").select(printed) == ["a 1", "...", "d 4"]
    assert Capture.parse("keep='^[bc]'").select(printed) == ["b 2", "c 3"]
    assert not Capture.parse("varies").differs("took 0.31 s", "took 12.5 s")
    assert Capture.parse("varies=wall").differs("took 0.31 s", "took 12.5 s")
    assert Capture.parse("").differs("took 0.31 s", "took 12.5 s")


def test_the_pages_have_examples_to_run() -> None:
    """The examples must not silently vanish: the README's quick start and the tutorial's steps run."""
    shell = [e for e in EXAMPLES if e.kind == "shell"]
    assert sum(e.text.startswith("netcfg ") for e in shell) >= 50
    for step in ("netcfg init", "netcfg check", "netcfg build", "netcfg simulate", "netcfg run", "netcfg verify"):
        assert any(e.page == "docs/tutorial.md" and e.text.startswith(step) for e in shell), step
    assert any(e.text.startswith("python examples/") for e in shell)


def test_the_readme_is_short_and_links_into_the_site() -> None:
    """What a newcomer reads first: at most 200 lines, and every link into docs/ names a page that exists."""
    import re

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= README_LINES
    links = re.findall(r"\]\((docs/[^)#]+)", text)
    assert links, "the README links into the site"
    assert [link for link in links if not (ROOT / link).is_file()] == []


_workdirs: dict[str, Workdir] = {}


@pytest.fixture
def workdir(example: Example, tmp_path_factory: pytest.TempPathFactory) -> Workdir:
    """The page's own working folder, made for its first example and kept for the ones after it."""
    if example.page not in _workdirs:
        _workdirs[example.page] = Workdir.make(tmp_path_factory.mktemp(Path(example.page).stem))
    return _workdirs[example.page]


@pytest.mark.parametrize("example", EXAMPLES, ids=[e.id for e in EXAMPLES])
def test_page_example_runs(example: Example, workdir: Workdir) -> None:
    proc = workdir.run(example)
    where = f"{example.page} line {example.line}"
    assert proc.returncode == example.exit_code, (
        f"{where} exits {proc.returncode}, not {example.exit_code}:\n{example.text}\n--- output\n{proc.stdout[-4000:]}"
    )
    if example.capture is not None:
        changed = capture_differences(example, proc.stdout)
        stale = f"{where}: the output shown is no longer what the command prints (make docs-snippets):\n"
        assert not changed, stale + "\n".join(changed)
    else:
        absent = missing_output(example.shown, proc.stdout)
        assert not absent, f"{where} shows output the command no longer prints:\n" + "\n".join(absent)
    if example.kind == "python":  # a program a user copies must leave nothing open (python-can warns of a bus)
        assert "not properly shut down" not in proc.stdout, f"{where}: {proc.stdout[-500:]}"


PAGE_FIGURES = [(p.relative_to(ROOT).as_posix(), figures_in(p.read_text(encoding="utf-8"))) for p in pages()]


def test_every_figure_a_page_quotes_is_registered() -> None:
    named = {name for _, figs in PAGE_FIGURES for name, _ in figs}
    assert named - set(FIGURES) == set()


@pytest.mark.parametrize("page", [p for p, figs in PAGE_FIGURES if figs])
def test_the_figures_a_page_quotes_are_what_the_commands_print(
    page: str, tmp_path_factory: pytest.TempPathFactory
) -> None:
    written = dict(next(figs for p, figs in PAGE_FIGURES if p == page))
    now = evaluate(set(written), Workdir.make(tmp_path_factory.mktemp("figures")))
    stale = {name: (written[name], now[name]) for name in written if written[name] != now[name]}
    assert not stale, f"{page}: figures no longer what the commands print (written, now; make docs-snippets): {stale}"
