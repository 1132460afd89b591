"""Longer runs of the property-based input suite (tests/test_hostile_fuzz.py) than CI's few examples per input.

    .venv/bin/python scripts/fuzz_inputs.py                # 500 examples per input, random seeds
    .venv/bin/python scripts/fuzz_inputs.py -n 5000 -k spec  # only the spec property, 5,000 examples

Prints pytest's summary; a failure shows hypothesis' smallest failing input. Exit code: pytest's.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", "--examples", type=int, default=500, help="examples per input (default 500)")
    parser.add_argument("-k", default=None, help="pytest -k expression: spec, eds, bus_yml, runtime_json, dbc")
    args = parser.parse_args()
    env = {**os.environ, "FUZZ_EXAMPLES": str(args.examples)}
    cmd = [sys.executable, "-m", "pytest", str(ROOT / "tests" / "test_hostile_fuzz.py"), "-q",
           "--hypothesis-show-statistics"]
    if args.k:
        cmd += ["-k", args.k]
    return subprocess.call(cmd, cwd=ROOT, env=env)


if __name__ == "__main__":
    sys.exit(main())
