"""Every command and Python example in the README runs as shown.

The README is read, not copied: any command line in a fenced block or an indented block that starts with `netcfg `
or `python ` is run through the shell, and every ```python block is run as a program, in a copy of the repository
(so `netcfg build` writes into the copy's generated/, never into the checkout). A line or block that cannot run in
CI says so visibly, with `not run in CI` and the reason beside it in its comment; that is the only way out.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.conftest import ROOT

OPT_OUT = "not run in CI"
COMMAND = re.compile(r"^(?:\$ )?((?:netcfg|python) .*)$")
FENCE = re.compile(r"^```(\w*)\s*$")


@dataclass(frozen=True)
class Example:
    line: int  # 1-based line in README.md, so a failure names where to look
    kind: str  # "shell" or "python"
    text: str
    exit_code: int = 0  # a command shown failing on purpose says `exits N` (or `exit N`) in its comment
    shown: tuple[str, ...] = ()  # output the README prints under a `$ ` command, which the command must print


    @property
    def id(self) -> str:
        first = self.text.strip().splitlines()[0]
        return f"L{self.line}:{first[:60]}"


def _strip_comment(line: str) -> str:
    """A shell line without its trailing `# comment` (README comments explain the command)."""
    return re.sub(r"\s+#.*$", "", line).rstrip()


def extract(markdown: str) -> list[Example]:
    """The runnable examples of a Markdown text: command lines of fenced/indented blocks, whole Python blocks."""
    lines = markdown.splitlines()
    examples: list[Example] = []
    i = 0
    while i < len(lines):
        fence = FENCE.match(lines[i])
        if fence:
            lang, start = fence.group(1), i + 1
            i += 1
            while i < len(lines) and not lines[i].startswith("```"):
                i += 1
            body = lines[start:i]
            i += 1
            if lang == "python":
                if any(OPT_OUT in b for b in body):
                    continue
                examples.append(Example(start + 1, "python", "\n".join(body) + "\n"))
            elif lang in ("", "sh", "bash", "shell", "console"):
                examples += _commands(body, start)
            continue
        # An indented block: four spaces after a blank line (or the document start), until a less-indented line.
        if lines[i].startswith("    ") and (i == 0 or not lines[i - 1].strip()):
            start = i
            while i < len(lines) and (lines[i].startswith("    ") or not lines[i].strip()):
                i += 1
            body = [b[4:] for b in lines[start:i]]
            if not any(OPT_OUT in b for b in body if not COMMAND.match(b.strip())):
                examples += _commands(body, start)
            continue
        i += 1
    return examples


def _commands(body: list[str], start: int) -> list[Example]:
    found = []
    for offset, raw in enumerate(body):
        match = COMMAND.match(raw.strip())
        if match and OPT_OUT not in raw:
            expected = re.search(r"#.*\bexits? (\d)\b", raw)
            code = int(expected.group(1)) if expected else 0
            shown: list[str] = []
            if raw.strip().startswith("$ "):  # its output follows, up to a blank line or the next command
                for line in body[offset + 1 :]:
                    if not line.strip() or COMMAND.match(line.strip()) or line.strip().startswith("$ "):
                        break
                    shown.append(line)
            found.append(Example(start + offset + 1, "shell", _strip_comment(match.group(1)), code, tuple(shown)))
    return found


def _words(text: str) -> str:
    return " ".join(text.split())


def missing_output(shown: tuple[str, ...], printed: str) -> list[str]:
    """The README's output lines the command did not print. '...' in a line stands for what the README leaves out,
    and lines the README wraps are matched piece by piece, so each piece must appear as printed."""
    out = _words(printed)
    return [line for line in shown if not all(_words(p) in out for p in line.split("...") if p.strip())]


EXAMPLES = extract((ROOT / "README.md").read_text(encoding="utf-8"))


def test_the_extractor_finds_fenced_indented_and_opted_out_blocks() -> None:
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
    ])
    got = [(e.line, e.kind, e.text, e.exit_code) for e in extract(text)]
    assert got == [
        (3, "shell", "netcfg check a.yaml", 0),
        (5, "shell", "python x.py --flag", 1),
        (8, "shell", "netcfg build a.yaml", 0),
        (13, "python", "print('hi')\n", 0),
    ]


def test_the_readme_has_examples_to_run() -> None:
    """The quick start alone has five netcfg commands; the README's examples must not silently vanish."""
    shell = [e for e in EXAMPLES if e.kind == "shell"]
    assert sum(e.text.startswith("netcfg ") for e in shell) >= 5
    assert any(e.text.startswith("python examples/") for e in shell)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of what the README's commands read and write, so the checkout is never touched."""
    work = tmp_path_factory.mktemp("readme")
    for name in ("specs", "generated", "examples", "tests/data"):  # tests/data: the DBC corpus the README checks
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, work / name)
    shutil.copy(ROOT / "README.md", work / "README.md")
    return work


@pytest.mark.parametrize("example", EXAMPLES, ids=[e.id for e in EXAMPLES])
def test_readme_example_runs(example: Example, workdir: Path) -> None:
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = str(ROOT)  # examples import netcfg from this checkout even when run from the copy
    env["MPLBACKEND"] = "Agg"
    if example.kind == "python":
        argv = [sys.executable, "-c", example.text]
    else:
        argv = ["bash", "-c", f"set -o pipefail; {example.text}"]
    proc = subprocess.run(argv, cwd=workdir, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == example.exit_code, (
        f"README.md line {example.line} exits {proc.returncode}, not {example.exit_code}:\n{example.text}\n"
        f"--- stdout\n{proc.stdout[-3000:]}\n--- stderr\n{proc.stderr[-3000:]}"
    )
    absent = missing_output(example.shown, proc.stdout + proc.stderr)
    assert not absent, f"README.md line {example.line} shows output the command no longer prints:\n" + "\n".join(
        absent
    )
    if example.kind == "python":  # a program a user copies must leave nothing open (python-can warns of a bus)
        assert "not properly shut down" not in proc.stderr, f"README.md line {example.line}: {proc.stderr[-500:]}"
