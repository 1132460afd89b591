"""The command line's reference page, generated from the argument parsers by running `netcfg --help`.

The help is read from the installed command, not from the module that builds the parser, so the page is right
wherever the parser lives. The commands come from the top-level help, each one's options from its own.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

# argparse wraps help at the terminal's width; one width for every build
HELP_ENV = {**os.environ, "COLUMNS": "100", "PYTHONIOENCODING": "utf-8"}
# the command list of the top-level help: "    check     validate specs ..."
COMMAND_LINE = re.compile(r"^ {4}([a-z][a-z-]*) {2,}(.*)$")


def help_text(*args: str) -> str:
    proc = subprocess.run(
        [sys.executable, "-m", "netcfg", *args, "--help"], capture_output=True, text=True, env=HELP_ENV, timeout=120
    )
    if proc.returncode != 0:
        raise SystemExit(f"netcfg {' '.join(args)} --help exited {proc.returncode}:\n{proc.stderr}")
    return proc.stdout.rstrip()


def commands(top: str) -> list[tuple[str, str]]:
    """(name, one-line help) of every subcommand the top-level help lists."""
    found = []
    for line in top.splitlines():
        match = COMMAND_LINE.match(line)
        if match:
            found.append((match.group(1), match.group(2).strip()))
    if not found:
        raise SystemExit("netcfg --help lists no commands: docs/gen/cli_reference.py no longer reads it right")
    return found


def cli_reference() -> str:
    """The generated part of the command line's reference page, as Markdown."""
    top = help_text()
    listed = commands(top)
    with ThreadPoolExecutor(max_workers=4) as pool:  # each help is a process of its own, mostly import time
        helps = list(pool.map(lambda c: help_text(c[0]), listed))
    out = ["## `netcfg`\n", "```text", top, "```\n"]
    for (name, summary), text in zip(listed, helps):
        out += [f"## `netcfg {name}`\n", summary[0].upper() + summary[1:] + ".\n", "```text", text, "```\n"]
    return "\n".join(out)


if __name__ == "__main__":
    print(cli_reference())
