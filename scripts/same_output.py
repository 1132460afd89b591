"""Everything netcfg produces, as one manifest of digests, so a restructuring can show it changed nothing.

    .venv/bin/python scripts/same_output.py --save before.json     # on the commit before the change
    .venv/bin/python scripts/same_output.py --compare before.json  # after it: exit 1 naming every output that moved

The manifest covers what the structure must keep byte for byte: every artifact `netcfg build` writes for each spec in
specs/ (the files under generated/), `netcfg check --format json` of every spec in specs/, examples/ and
tests/bad_specs/ (its output, its messages on stderr and its exit code), and the simulator's fingerprints
(scripts/sim_fingerprints.py). It runs the commands as a user does, as processes, so it does not depend on where a
command's code lives.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
NETCFG = [sys.executable, "-m", "netcfg"]


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:20]


def _run(args: list[str]) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run(args, cwd=ROOT, capture_output=True, check=False)


def build_digests(spec: Path) -> dict[str, str]:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / spec.stem
        done = _run([*NETCFG, "build", str(spec.relative_to(ROOT)), "-o", str(out)])
        digests = {"exit": str(done.returncode)}
        for f in sorted(out.rglob("*")):
            if f.is_file():
                digests[str(f.relative_to(out))] = _sha(f.read_bytes())
        return digests


def check_digest(spec: Path) -> str:
    done = _run([*NETCFG, "check", str(spec.relative_to(ROOT)), "--format", "json"])
    return f"{done.returncode} {_sha(done.stdout)} {_sha(done.stderr)}"


def fingerprint_digest() -> str:
    code = (
        "import sys; sys.path.insert(0, 'scripts'); import sim_fingerprints as s; "
        "sys.stdout.write(s.render(s.all_fingerprints()))"
    )
    done = _run([sys.executable, "-c", code])
    if done.returncode != 0:
        return f"failed: {done.stderr.decode(errors='replace')[-300:]}"
    return _sha(done.stdout)


def manifest() -> dict[str, object]:
    specs = sorted((ROOT / "specs").glob("*.yaml"))
    checked = [
        *specs,
        *sorted((ROOT / "examples").glob("*.yaml")),
        *sorted((ROOT / "tests" / "bad_specs").glob("*.y*ml")),
    ]
    with ThreadPoolExecutor(max_workers=2) as pool:  # each job is a process of its own
        builds = dict(zip([s.stem for s in specs], pool.map(build_digests, specs)))
        checks = dict(zip([str(s.relative_to(ROOT)) for s in checked], pool.map(check_digest, checked)))
    return {"build": builds, "check": checks, "sim_fingerprints": fingerprint_digest()}


def differences(before: object, after: object, where: str = "") -> list[str]:
    if isinstance(before, dict) and isinstance(after, dict):
        out = []
        for key in sorted(set(before) | set(after)):
            at = f"{where}/{key}" if where else key
            if key not in after:
                out.append(f"{at}: gone")
            elif key not in before:
                out.append(f"{at}: new")
            else:
                out.extend(differences(before[key], after[key], at))
        return out
    return [] if before == after else [f"{where}: {before} -> {after}"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--save", type=Path, metavar="FILE", help="write the manifest of the current tree")
    what.add_argument("--compare", type=Path, metavar="FILE", help="compare the current tree with a saved manifest")
    args = parser.parse_args()
    now = manifest()
    if args.save:
        args.save.write_text(json.dumps(now, indent=1, sort_keys=True) + "\n", encoding="utf-8")
        print(f"wrote {args.save}: {len(now['build'])} builds, {len(now['check'])} checks")  # type: ignore[arg-type]
        return 0
    moved = differences(json.loads(args.compare.read_text(encoding="utf-8")), now)
    for line in moved:
        print(line)
    print("same output" if not moved else f"{len(moved)} outputs changed")
    return 1 if moved else 0


if __name__ == "__main__":
    sys.exit(main())
