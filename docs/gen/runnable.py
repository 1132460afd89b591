"""The runnable examples of the documentation: what a page shows, run as shown.

A page (README.md or docs/**/*.md) is read, not copied:

- a command line in a fenced block (```, ```console, ```sh, ...) or in an indented block that starts with `netcfg `
  or `python ` (after an optional `$ ` prompt) runs through the shell; `# exits N` in its comment is the exit code it
  must give, `# not run in CI: why` leaves it out (real hardware, a file only a robot has);
- a ```python block runs as a program;
- a fenced block with a title (```yaml title="robot.yaml") is a file the reader writes: it is written into the
  working folder before the commands after it run;
- the lines under a `$ ` command, up to a blank line or the next command, are output the command must print
  ('...' stands for what the page leaves out);
- a ```console block right after a line `<!-- output -->` is the commands' real output, written by
  `make docs-snippets` (docs/gen/refresh.py) and compared line for line by the test. Options:
  `<!-- output: head=N tail=N keep=REGEX varies=REGEX -->` keep the first or last N lines (a `...` line between),
  only lines matching keep, and compare lines matching varies (all lines for a bare `varies`) with their numbers
  masked: times a host measures;
- a figure in prose, `<!--fig NAME-->67.9 %<!--/fig-->`, is the value docs/gen/figures.py computes for NAME from
  a command's output, also written by `make docs-snippets` and compared by the test.

Every page's examples run in order, in a working folder of their own that holds a copy of what the commands read
(specs/, generated/, examples/, tests/data/), so the checkout is never written to.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OPT_OUT = "not run in CI"
COMMAND = re.compile(r"^(?:\$ )?((?:netcfg|python) .*)$")
FENCE = re.compile(r"^(\s*)```(\w*)(.*)$")
TITLE = re.compile(r'title="([^"]+)"')
OUTPUT_MARK = re.compile(r"^<!-- output(?::(.*))? -->\s*$")
FIGURE = re.compile(r"(?<!`)<!--fig ([\w.-]+)-->(.*?)<!--/fig-->")  # not in a code span, where a page shows the form
SHELL_FENCES = ("", "sh", "bash", "shell", "console")
COPIED = ("specs", "generated", "examples", "tests/data")  # tests/data: the DBC corpus the pages check
NUMBER = re.compile(r"\d[\d,]*(?:\.\d+)?")


@dataclass(frozen=True)
class Capture:
    """How a command's real output is shown: which lines, and which of them a host's timing changes."""

    head: int = 0
    tail: int = 0
    keep: str = ""
    varies: str | None = None  # a regex; "" for every line

    @classmethod
    def parse(cls, options: str | None) -> Capture:
        capture = cls()
        for option in shlex.split(options or ""):
            key, _, value = option.partition("=")
            if key == "head":
                capture = replace(capture, head=int(value))
            elif key == "tail":
                capture = replace(capture, tail=int(value))
            elif key == "keep":
                capture = replace(capture, keep=value)
            elif key == "varies":
                capture = replace(capture, varies=value)
            else:
                raise ValueError(f"unknown output option {option!r} (head=N, tail=N, keep=REGEX, varies[=REGEX])")
        return capture

    def select(self, printed: str) -> list[str]:
        lines = [line.rstrip() for line in printed.rstrip().splitlines()]
        if self.keep:
            lines = [line for line in lines if re.search(self.keep, line)]
        head, tail = self.head, self.tail
        if (head or tail) and len(lines) > head + tail:
            lines = lines[:head] + ["..."] + (lines[-tail:] if tail else [])
        return lines

    def differs(self, shown: str, printed: str) -> bool:
        if self.varies is not None and re.search(self.varies, shown + "\n" + printed):
            return _masked(shown) != _masked(printed)
        return shown != printed


def _masked(line: str) -> str:
    return " ".join(NUMBER.sub("N", line).split())


@dataclass(frozen=True)
class Example:
    page: str  # the page's path from the repository's root, so a failure names where to look
    line: int  # 1-based line of the command, program or file in the page
    kind: str  # "shell", "python" or "file"
    text: str
    exit_code: int = 0
    shown: tuple[str, ...] = ()
    capture: Capture | None = None
    output_lines: tuple[int, int] = (0, 0)  # 0-based [start, end) of the shown output in the page, for a capture
    file_name: str = ""
    prompt_line: str = ""  # the command's line as the page writes it, comment included

    @property
    def id(self) -> str:
        first = self.text.strip().splitlines()[0] if self.kind != "file" else f"writes {self.file_name}"
        return f"{self.page}:L{self.line}:{first[:60]}"


def _strip_comment(line: str) -> str:
    """A shell line without its trailing `# comment` (comments explain the command to the reader)."""
    return re.sub(r"\s+#.*$", "", line).rstrip()


def extract(markdown: str, page: str = "<text>") -> list[Example]:
    """The runnable examples of a Markdown text, in the order a reader meets them."""
    lines = markdown.splitlines()
    examples: list[Example] = []
    i = 0
    while i < len(lines):
        fence = FENCE.match(lines[i])
        if fence:
            indent, lang, info = fence.groups()
            mark = _output_mark(lines, i)
            start = i + 1
            i += 1
            while i < len(lines) and not lines[i].strip().startswith("```"):
                i += 1
            body = [b[len(indent) :] if b.startswith(indent) else b.lstrip() for b in lines[start:i]]
            i += 1
            title = TITLE.search(info)
            if title and lang not in SHELL_FENCES:
                examples.append(Example(page, start + 1, "file", "\n".join(body) + "\n", file_name=title.group(1)))
            elif lang == "python":
                if not any(OPT_OUT in b for b in body):
                    examples.append(Example(page, start + 1, "python", "\n".join(body) + "\n"))
            elif lang in SHELL_FENCES:
                capture = Capture.parse(mark) if mark is not None else None
                examples += _commands(body, start, page, capture)
            continue
        # An indented block: four spaces after a blank line (or the document start), until a less-indented line.
        if lines[i].startswith("    ") and (i == 0 or not lines[i - 1].strip()):
            start = i
            while i < len(lines) and (lines[i].startswith("    ") or not lines[i].strip()):
                i += 1
            body = [b[4:] for b in lines[start:i]]
            if not any(OPT_OUT in b for b in body if not COMMAND.match(b.strip())):
                examples += _commands(body, start, page, None)
            continue
        i += 1
    return examples


def _output_mark(lines: list[str], fence_index: int) -> str | None:
    """The options of an `<!-- output -->` line right before a fence (None: the block is not a capture)."""
    j = fence_index - 1
    while j >= 0 and not lines[j].strip():
        j -= 1
    if j < 0:
        return None
    mark = OUTPUT_MARK.match(lines[j].strip())
    return None if mark is None else (mark.group(1) or "")


def _commands(body: list[str], start: int, page: str, capture: Capture | None) -> list[Example]:
    found = []
    for offset, raw in enumerate(body):
        match = COMMAND.match(raw.strip())
        if not match or OPT_OUT in raw or (capture is not None and not raw.strip().startswith("$ ")):
            continue  # in a captured block only `$ ` lines are commands: the rest is what they printed
        expected = re.search(r"#.*\bexits? (\d)\b", raw)
        code = int(expected.group(1)) if expected else 0
        shown: list[str] = []
        if raw.strip().startswith("$ "):  # its output follows, up to the next command (or a blank line, loosely)
            for line in body[offset + 1 :]:
                if line.strip().startswith("$ "):
                    break
                if capture is None and (not line.strip() or COMMAND.match(line.strip())):
                    break
                shown.append(line.rstrip())
        while capture is not None and shown and not shown[-1]:
            shown.pop()
        first = start + offset + 1  # 0-based index of the first output line in the page
        found.append(
            Example(
                page,
                start + offset + 1,
                "shell",
                _strip_comment(match.group(1)),
                code,
                tuple(shown),
                capture,
                (first, first + len(shown)),
                prompt_line=raw.strip(),
            )
        )
    return found


def missing_output(shown: tuple[str, ...], printed: str) -> list[str]:
    """The page's output lines the command did not print. '...' in a line stands for what the page leaves out,
    and lines the page wraps are matched piece by piece, so each piece must appear as printed."""
    out = " ".join(printed.split())
    return [line for line in shown if not all(" ".join(p.split()) in out for p in line.split("...") if p.strip())]


def capture_differences(example: Example, printed: str) -> list[str]:
    """For a captured output block: the lines where the page and the command's output now part."""
    assert example.capture is not None
    now = example.capture.select(printed)
    if len(now) != len(example.shown):
        count = f"the page shows {len(example.shown)} lines, the command now prints {len(now)}"
        return [count, *_diff(list(example.shown), now)]
    return [
        f"page: {shown}\n  now: {new}"
        for shown, new in zip(example.shown, now)
        if example.capture.differs(shown, new)
    ]


def _diff(old: list[str], new: list[str]) -> list[str]:
    import difflib

    return list(difflib.unified_diff(old, new, "page", "now", lineterm="", n=1))[:40]


@dataclass
class Workdir:
    """A folder of one page's own, with a copy of what the commands read; the page's examples run in it in order."""

    path: Path
    ran: list[str] = field(default_factory=list)

    @classmethod
    def make(cls, path: Path) -> Workdir:
        path.mkdir(parents=True, exist_ok=True)
        for name in COPIED:
            if (ROOT / name).is_dir():
                shutil.copytree(ROOT / name, path / name, dirs_exist_ok=True)
        shutil.copy(ROOT / "README.md", path / "README.md")
        return cls(path)

    def env(self) -> dict[str, str]:
        env = dict(os.environ)
        env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
        env["PYTHONPATH"] = str(ROOT)  # examples import netcfg from this checkout even when run from the copy
        env["MPLBACKEND"] = "Agg"
        env["PYTHONUNBUFFERED"] = "1"  # standard output and error interleaved as on a terminal
        env["COLUMNS"] = "100"
        return env

    def run(self, example: Example, merge: bool = True) -> subprocess.CompletedProcess[str]:
        """Run one example; its output is standard output and error together (unless not merge), with this
        folder's path taken out."""
        self.ran.append(example.id)
        if example.kind == "file":
            target = self.path / example.file_name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(example.text, encoding="utf-8")
            return subprocess.CompletedProcess([], 0, "", "")
        if example.kind == "python":
            argv = [sys.executable, "-c", example.text]
        else:
            argv = ["bash", "-c", f"set -o pipefail; {example.text}"]
        proc = subprocess.run(
            argv,
            cwd=self.path,
            env=self.env(),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT if merge else subprocess.PIPE,
            text=True,
            timeout=300,
        )
        proc.stdout = proc.stdout.replace(f"{self.path}{os.sep}", "").replace(str(self.path), ".")
        return proc


def pages() -> list[Path]:
    """README.md and every page of the site, in a stable order."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def page_examples() -> Iterator[Example]:
    for path in pages():
        yield from extract(path.read_text(encoding="utf-8"), path.relative_to(ROOT).as_posix())


def rewrite_captures(markdown: str, outputs: dict[int, list[str]], examples: list[Example]) -> str:
    """The page with each captured block's output replaced by the command's output now (keyed by command line)."""
    lines = markdown.splitlines()
    for example in sorted(examples, key=lambda e: e.line, reverse=True):
        if example.capture is None or example.line not in outputs:
            continue
        start, end = example.output_lines
        lines[start:end] = outputs[example.line]
    return "\n".join(lines) + ("\n" if markdown.endswith("\n") else "")


def figures_in(markdown: str) -> list[tuple[str, str]]:
    """(name, value as written) of every figure in a page."""
    return [(m.group(1), m.group(2)) for m in FIGURE.finditer(markdown)]


def rewrite_figures(markdown: str, values: dict[str, str]) -> str:
    return FIGURE.sub(lambda m: f"<!--fig {m.group(1)}-->{values.get(m.group(1), m.group(2))}<!--/fig-->", markdown)
