"""`--fault ...@T` times read with the one unit grammar of specs and the command line (netcfg.spec.units), not a
parser of their own: whatever a spec's duration accepts, a fault time accepts, and it means the same nanoseconds.

The reference is netcfg.spec.units.parse_duration (the spec's reader) and the hand conversions in the table.
"""

from __future__ import annotations

import pytest
from conftest import cli

from netcfg.sim.faults import Fault, FaultError
from netcfg.spec.units import parse_duration

# (text, nanoseconds by hand): 1 s = 10^9 ns, 1 ms = 10^6 ns, 1 us = 10^3 ns
TIMES = [
    ("12.5ms", 12_500_000),
    ("12.5 ms", 12_500_000),
    ("250us", 250_000),
    ("250 µs", 250_000),
    ("2s", 2_000_000_000),
    ("1e3 ms", 1_000_000_000),
    (".5ms", 500_000),
    ("0", 0),
    ("0 ms", 0),
]


@pytest.mark.parametrize(("text", "ns"), TIMES)
def test_every_fault_reads_its_time_as_a_spec_duration(text: str, ns: int) -> None:
    if text != "0":  # a spec writes a bare 0 as the integer 0, which the same reader takes
        assert parse_duration(text).ns == ns
    assert Fault.parse(f"bit-error@{text}").at_ns == ns
    assert Fault.parse(f"bit-error@{text}:can0") == Fault("bit-error", "can0", ns)
    assert Fault.parse(f"crash:knee_r@{text}") == Fault("crash", "knee_r", ns)
    assert Fault.parse(f"lose:hip_l_cmd@{text}") == Fault("lose", "hip_l_cmd", ns)
    assert Fault.parse(f"master-fail@{text}:backup") == Fault("master-fail", "backup", ns)
    babble = Fault.parse(f"babble:knee_r@{text}..3 s=0x10")
    assert (babble.at_ns, babble.until_ns, babble.value) == (ns, 3_000_000_000, 16.0)


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("crash:knee_r@2", "cannot read '2' as a duration"),  # a bare number: seconds or milliseconds?
        ("crash:knee_r@1.5ns", "finer than 1 ns"),
        ("crash:knee_r@5 EC", "EC only exists inside a spec"),
        ("crash:knee_r@2 fortnights", "unknown time unit 'fortnights'"),
        ("crash:knee_r@99999999 s", "longer than netcfg handles"),
        ("babble:knee_r@2s..1s", "ends before it starts"),
    ],
)
def test_a_bad_fault_time_says_what_the_grammar_wants(text: str, says: str) -> None:
    with pytest.raises(FaultError, match=says.replace(".", r"\.")):
        Fault.parse(text)


def test_the_command_line_refuses_a_bad_fault_time_in_one_line() -> None:
    proc = cli("simulate", "specs/allex2.yaml", "--duration", "20ms", "--fault", "crash:knee_r@2")
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "cannot read '2' as a duration" in proc.stderr
    assert "Traceback" not in proc.stderr and proc.stdout == ""
