"""The random specs of benchmarks/soundness.py set every field of the spec language, so that no field (and no new
one) escapes the soundness sweep: defects where features meet hid in fields it never drew (a drive's tx_delay, a
TPDO's event timer, an asynchronous FTT-CAN id below the trigger message's, ...).

The schema's field paths are walked from netcfg.spec.schema.Spec through every pydantic model it reaches
(`buses[].canopen.sync_period`); the generator's are the key paths present in specs it draws with a fixed seed.
A field the generator never sets fails here, by name, unless NOT_DRAWN says why it is left out.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, Literal, get_args, get_origin

import pytest
import soundness
from hypothesis import HealthCheck, Phase, given, seed, settings
from pydantic import BaseModel

from netcfg.spec.schema import Spec

# Fields the generator leaves out on purpose, each with its reason. Keep it short: a field that changes what
# check or simulate does belongs in a strategy.
NOT_DRAWN = {
    # free text: no analysis, emitter of timing or simulator reads it
    "description": "free text",
    "buses[].description": "free text",
    "nodes[].description": "free text",
    "nodes[].tasks[].description": "free text",
    "messages[].description": "free text",
    "triggers[].description": "free text",
    "flows[].description": "free text",
    "joints[].description": "free text",
    # a DBC file beside the spec: its nodes and messages are plain CAN ones, which the generator draws directly
    "buses[].import": "a DBC file to import",
}

SPECS_PER_PROTOCOL = 200  # enough for every field and choice drawn one time in twenty or more: generated, never run


def _models(annotation: Any, many: bool = False) -> Iterator[tuple[type[BaseModel], bool]]:
    """The pydantic models inside a field's type, each with whether it sits in a list (or tuple)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        yield annotation, many
        return
    inner = many or get_origin(annotation) in (list, tuple)
    for arg in get_args(annotation):
        yield from _models(arg, inner)


def schema_fields(model: type[BaseModel] = Spec, prefix: str = "") -> dict[str, Any]:
    """Every field path of the spec language -> its type: `buses[].canopen.sync_period`."""
    out: dict[str, Any] = {}
    for name, info in model.model_fields.items():
        path = prefix + (info.alias or name)
        out[path] = info.annotation
        for sub, many in _models(info.annotation):
            out |= schema_fields(sub, path + ("[]." if many else "."))
    return out


def key_paths(obj: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(path, value) of every key in a spec's plain data, lists written `[]` as in schema_fields."""
    if isinstance(obj, dict):
        for key, value in obj.items():
            yield prefix + str(key), value
            yield from key_paths(value, f"{prefix}{key}.")
    elif isinstance(obj, list):
        for item in obj:
            yield from key_paths(item, prefix.removesuffix(".") + "[].")


def literals(annotation: Any) -> set[Any]:
    """The values a Literal inside a field's type allows (none for other types)."""
    if get_origin(annotation) is Literal:
        return set(get_args(annotation))
    return set().union(*(literals(arg) for arg in get_args(annotation)))


def drawn(protocols: tuple[str, ...] = soundness.PROTOCOLS, held: frozenset[str] = frozenset(),
          examples: int = SPECS_PER_PROTOCOL) -> dict[str, set[Any]]:
    """Field path -> the plain values (str, int, float, bool) the generator set there, over `examples` specs of
    each protocol drawn with a fixed seed."""
    seen: dict[str, set[Any]] = {}
    for protocol in protocols:

        @seed(20261201)
        @settings(max_examples=examples, database=None, deadline=None, phases=[Phase.generate],
                  suppress_health_check=list(HealthCheck))
        @given(soundness.strategy(protocol, held))
        def collect(spec: dict[str, Any]) -> None:
            for path, value in key_paths(spec):
                seen.setdefault(path, set())
                if isinstance(value, str | int | float):
                    seen[path].add(value)

        collect()
    return seen


@pytest.fixture(scope="module")
def seen() -> dict[str, set[Any]]:
    return drawn()


def test_the_schema_walk_reaches_nested_models() -> None:
    """The walk itself: fields four models deep, behind a list, an Optional, a union with a name, an alias."""
    fields = schema_fields()
    for path in ("buses[].canopen.sync_period", "buses[].ethernet.switches[].ports[].cable",
                 "messages[].pdo.map[].object", "nodes[].device.eds", "nodes[].tx_queue.on_full",
                 "messages[].signals[].mux.values", "buses[].import"):
        assert path in fields, path


def test_every_schema_field_is_drawn(seen: dict[str, set[Any]]) -> None:
    fields = schema_fields()
    missing = sorted(set(fields) - set(seen) - set(NOT_DRAWN))
    assert not missing, f"the soundness generator never sets {missing}: draw them (benchmarks/soundness.py) or " \
        "say in NOT_DRAWN why not"


def test_the_exclusions_are_schema_fields_the_generator_leaves_out(seen: dict[str, set[Any]]) -> None:
    fields = schema_fields()
    assert not sorted(set(NOT_DRAWN) - set(fields)), "NOT_DRAWN names fields the schema no longer has"
    assert not sorted(set(NOT_DRAWN) & set(seen)), "NOT_DRAWN names fields the generator now draws"


def test_every_choice_of_a_field_is_drawn(seen: dict[str, set[Any]]) -> None:
    """A field with a fixed set of values (a Literal: protocol, windows, on_full, type ...) gets each of them."""
    gaps = {}
    for path, annotation in schema_fields().items():
        allowed = literals(annotation)
        if allowed and path not in NOT_DRAWN and allowed - seen.get(path, set()):
            gaps[path] = sorted(map(str, allowed - seen.get(path, set())))
    assert not gaps, f"values the soundness generator never draws: {gaps}"


def test_held_fields_and_features_are_left_out() -> None:
    """What a sweep holds back (soundness.HELD, `--hold`) never appears, and holding it is the only change: a
    field the strategies draw often is absent with it held and present without."""
    held = frozenset({"nodes[].tx_delay", "buses[].errors", "messages[].pdo.event_timer"})
    paths = drawn(held=held, examples=40)
    assert not held & set(paths)
    assert held <= set(drawn(examples=40))


def test_held_entries_name_schema_fields_or_features() -> None:
    fields = schema_fields()
    for protocol, entries in soundness.HELD.items():
        assert protocol in soundness.PROTOCOLS
        for key, reason in entries.items():
            assert reason, key
            if "[]" in key or "." in key:  # a field path, not a feature's name
                assert key in fields, f"HELD names {key}, which the schema does not have"


def test_strip_takes_a_field_away_wherever_it_is() -> None:
    """The classifier's ablation: every node loses its tx_delay, nothing else moves, the spec itself is intact."""
    spec = {"nodes": [{"name": "a", "tx_delay": "3 ms", "rx_delay": "1 us"}, {"name": "b"},
                      {"name": "c", "tx_delay": "10 us"}]}
    assert soundness.strip(spec, "nodes[].tx_delay") == {
        "nodes": [{"name": "a", "rx_delay": "1 us"}, {"name": "b"}, {"name": "c"}]}
    assert spec["nodes"][0]["tx_delay"] == "3 ms"


def test_lost_frames_and_incomplete_sync_cycles_are_violations() -> None:
    """A run of an accepted spec may not lose frames or miss a read window. The figures are seam 11's (a FIFO of
    depth 2 with on_full: drop, three 10 ms frames: m2 dropped every period, 20 in 200 ms) and seam 01's (a TPDO
    queued 3 ms after SYNC, read window 2 ms: every one of the 20 cycles of 200 ms incomplete)."""
    result = {"lost": 20, "tx_queues": [{"node": "host", "overflows": 20}],
              "protocols": {"can0": [{"cycles": 20, "incomplete_cycles": 20, "collection_us": {"max": 2000.001}}]}}
    broken = soundness._promises_broken(result)
    assert broken == ["20 frames lost (host dropped 20)",
                      "bus can0: 20 of 20 SYNC cycles incomplete (collection up to 2000.001 us)"]
    assert [soundness.subject(f"random phases: {v}") for v in broken] == ["frames lost", "bus can0"]
    assert soundness._promises_broken({"lost": 0, "protocols": {"can0": [{"cycles": 20, "incomplete_cycles": 0}]}}) \
        == []
    # seam 11 with m2 marked may_be_lost: its 20 dropped frames are what the spec allows
    allowed = {"lost": 20, "messages": [{"name": "m2", "lost": 20}], "protocols": {}}
    assert soundness._promises_broken(allowed, frozenset({"m2"})) == []


def test_ethercat_draws_tasks_on_the_cycle() -> None:
    """A field an older protocol already draws can gain a meaning on a new one: `sync` on an EtherCAT master's task
    and a DC slave's is drawn by the EtherCAT strategy itself, not only by CANopen's, both as `true` and naming the
    bus."""
    assert {True, "ecat"} <= drawn(("ethercat",), examples=60).get("nodes[].tasks[].sync", set())
