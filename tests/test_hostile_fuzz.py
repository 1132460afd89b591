"""Property-based: every input netcfg reads (spec, EDS/DCF, DBC, bus.yml, runtime.json), mutated at random in its
types, ranges, units, references, encodings, sizes and YAML features (anchors, merge keys, tags, several
documents), keeps the input contract: exit 0, 1 or 2; never a traceback or an internal error; a message whenever
it refuses; nothing written when it refuses; the user's files beside it untouched.

CI runs a few examples per input (FUZZ_EXAMPLES, default 12); scripts/fuzz_inputs.py runs many more.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import yaml
from conftest import ROOT
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_hostile_inputs import BUS_YML, DBC, EDS, EDS_SPEC, MINI

from netcfg.commands import main

EXAMPLES = int(os.environ.get("FUZZ_EXAMPLES", "12"))
FUZZ = settings(max_examples=EXAMPLES, deadline=None, derandomize=EXAMPLES <= 12,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

# values a field may be given instead of its own: wrong types, edges of ranges, units, references, hostile text
VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.sampled_from([0, -1, 1, 7, 8, 9, 64, 65, 127, 128, 0x7FF, 0x800, 2**29, 2**31, 2**32, 2**63, 10**40]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(["", "0 ms", "1 ns", "5 ms", "1e1000000 ms", "1e-30 s", "\u0661\u0660 ms", "nan ms", "2 EC",
                     "15 kHz", "1e999999999 Hz", "250 kbit/s", "0 bit/s", "x", "../../x", "a */ b", "auto", "a",
                     "b", "m1", "can0", "master", "drive", "ghost", "9" * 5000, "\x00", "periodic", "bogus"]),
    st.text(max_size=20),
    st.lists(st.sampled_from(["a", "b", "m1", "ghost", 1]), max_size=3),
    st.dictionaries(st.sampled_from(["name", "x", "period", "size"]), st.sampled_from(["a", 1, "5 ms"]), max_size=2),
)


def paths(data: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every path to a value inside nested dicts and lists."""
    out = [prefix] if prefix else []
    if isinstance(data, dict):
        for k, v in data.items():
            out += paths(v, (*prefix, k))
    elif isinstance(data, list):
        for n, v in enumerate(data):
            out += paths(v, (*prefix, n))
    return out


def replaced(data: Any, path: tuple[Any, ...], value: Any) -> Any:
    if not path:
        return value
    head, rest = path[0], path[1:]
    if isinstance(data, dict):
        return {k: (replaced(v, rest, value) if k == head else v) for k, v in data.items()}
    return [replaced(v, rest, value) if n == head else v for n, v in enumerate(data)]


@st.composite
def structural(draw: st.DrawFn, data: Any) -> Any:
    """data with one to three values replaced, removed or duplicated."""
    for _ in range(draw(st.integers(1, 3))):
        where = draw(st.sampled_from(paths(data)))
        action = draw(st.sampled_from(["value", "value", "drop", "duplicate"]))
        if action == "value":
            data = replaced(data, where, draw(VALUES))
        else:
            parent = where[:-1]
            node: Any = data
            for part in parent:
                node = node[part]
            if isinstance(node, list):
                items = list(node)
                if action == "drop":
                    del items[where[-1]]
                else:
                    items.append(items[where[-1]])
                data = replaced(data, parent, items)
            elif isinstance(node, dict) and action == "drop":
                data = replaced(data, parent, {k: v for k, v in node.items() if k != where[-1]})
    return data


def _yaml_features(text: str, draw: st.DrawFn) -> str:
    lines = text.splitlines()
    n = draw(st.integers(0, max(0, len(lines) - 1)))
    feature = draw(st.sampled_from(["anchor-merge", "tag", "documents", "alias-bomb", "deep", "tab"]))
    if feature == "anchor-merge":
        return "x-base: &base {size: 8, period: 10 ms}\n" + text.replace("size: 8", "<<: *base", 1)
    if feature == "tag":
        tag = draw(st.sampled_from(["!!int", "!!float", "!!bool", "!!str", "!!binary", "!!set", "!!timestamp",
                                    "!custom", "!!python/name:os.system"]))
        line = lines[n]
        if ": " in line:
            key, _, value = line.partition(": ")
            lines[n] = f"{key}: {tag} {value}"
        return "\n".join(lines) + "\n"
    if feature == "documents":
        return text + "---\n" + text
    if feature == "alias-bomb":
        bomb = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
            f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n"
            for p, c in zip("abcdefg", "bcdefgh"))
        return bomb + text
    if feature == "deep":
        return text + "description: " + "[" * 2000 + "]" * 2000 + "\n"
    lines[n] = "\t" + lines[n]
    return "\n".join(lines) + "\n"


@st.composite
def textual(draw: st.DrawFn, text: str, is_yaml: bool) -> bytes:
    """text damaged as bytes: an encoding, a truncation, inserted bytes, an extreme number, a YAML feature."""
    kind = draw(st.sampled_from(["encoding", "truncate", "insert", "number", "yaml" if is_yaml else "number"]))
    if kind == "yaml":
        return _yaml_features(text, draw).encode()
    raw = text.encode()
    if kind == "encoding":
        codec = draw(st.sampled_from(["utf-8-sig", "utf-16", "cp1252", "latin-1", "utf-32"]))
        return text.replace("Acme", "Acme Gm\u00fcnd \u00b5s").encode(codec, errors="replace")
    if kind == "truncate":
        return raw[: draw(st.integers(0, len(raw)))]
    at = draw(st.integers(0, len(raw)))
    if kind == "insert":
        return raw[:at] + draw(st.binary(min_size=1, max_size=8)) + raw[at:]
    numbers = [i for i, ch in enumerate(text) if ch.isdigit()]
    if not numbers:
        return raw
    i = draw(st.sampled_from(numbers))
    extreme = draw(st.sampled_from(["9" * 5000, "1e400", "-5", "0", "4294967296", "\u0665", "0x7FFFFFFF", "nan"]))
    return (text[:i] + extreme + text[i + 1 :]).encode()


def run_cli(*args: str) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            rc = main(list(args))
        except SystemExit as exc:
            rc = exc.code if isinstance(exc.code, int) else 2
    return rc, err.getvalue()


def contract(folder: Path, files: dict[str, bytes], command: Callable[[Path], list[str]], output: str | None) -> None:
    """Write files into folder with a user's file beside them, run the command, and hold it to the contract."""
    for name, data in files.items():
        (folder / name).write_bytes(data)
    (folder / "mine.txt").write_text("the user's")
    before = sorted(p.name for p in folder.iterdir())
    rc, err = run_cli(*command(folder))
    assert rc in (0, 1, 2), (rc, err)
    assert "Traceback" not in err and "internal error" not in err, err
    if rc != 0:
        assert err.strip(), "refused without a message"
        assert sorted(p.name for p in folder.iterdir()) == before, "a refused command wrote something"
    elif output is None:
        assert sorted(p.name for p in folder.iterdir()) == before, "a command that writes nothing wrote something"
    assert (folder / "mine.txt").read_text() == "the user's"


def spec_data() -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load(MINI.replace("SIZE", "8"))
    return data


@contextlib.contextmanager
def workdir() -> Iterator[Path]:
    """A fresh temporary folder, the current one while the example runs (relative outputs land there)."""
    with tempfile.TemporaryDirectory() as tmp:
        cwd = os.getcwd()
        os.chdir(tmp)
        try:
            yield Path(tmp)
        finally:
            os.chdir(cwd)


@FUZZ
@given(st.one_of(structural(spec_data()).map(lambda d: yaml.safe_dump(d, sort_keys=False).encode()),
                 textual(MINI.replace("SIZE", "8"), True)))
def test_spec(mutated: bytes) -> None:
    with workdir() as folder:
        contract(folder, {"spec.yaml": mutated}, lambda f: ["check", str(f / "spec.yaml")], None)
    with workdir() as folder:
        contract(folder, {"spec.yaml": mutated}, lambda f: ["build", str(f / "spec.yaml"), "-o", str(f / "out")], "out")


@FUZZ
@given(textual(EDS, False))
def test_eds(mutated: bytes) -> None:
    spec = EDS_SPEC.replace("EDSPATH", "dev.eds").encode()
    with workdir() as folder:
        contract(folder, {"dev.eds": mutated, "spec.yaml": spec},
                 lambda f: ["build", str(f / "spec.yaml"), "-o", str(f / "out")], "out")


def bus_yml_data() -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load(BUS_YML)
    return data


@FUZZ
@given(st.one_of(structural(bus_yml_data()).map(lambda d: yaml.safe_dump(d, sort_keys=False).encode()),
                 textual(BUS_YML, True)),
       textual(EDS.replace("FileName=dev.eds", "FileName=dev.dcf"), False))
def test_bus_yml(mutated: bytes, dcf: bytes) -> None:
    with workdir() as folder:
        contract(folder, {"bus.yml": mutated, "dev.eds": dcf},
                 lambda f: ["import", "bus-yml", str(f / "bus.yml"), "-o", str(f / "spec.yaml")], "spec.yaml")


RUNTIME = json.loads((ROOT / "generated" / "allex2" / "runtime.json").read_text())


@FUZZ
@given(st.one_of(structural(RUNTIME).map(lambda d: json.dumps(d, default=str).encode()),
                 textual(json.dumps(RUNTIME), False)))
def test_runtime_json(mutated: bytes) -> None:
    with workdir() as folder:
        contract(folder, {"runtime.json": mutated},
                 lambda f: ["simulate", str(f / "runtime.json"), "--duration", "10ms", "--max-events", "100000"], None)


@FUZZ
@given(textual(DBC, False).filter(lambda b: b"9" * 100 not in b and b"1e400" not in b))
def test_dbc(mutated: bytes) -> None:
    """Encodings, truncations, inserted bytes and small numbers; the DBC importer's own range checks (huge numbers,
    signal sizes) are that importer's tests."""
    with workdir() as folder:
        contract(folder, {"a.dbc": mutated}, lambda f: ["check", str(f / "a.dbc")], None)
