"""Hostile DBC input: a clear error at the DBC's own line, exit 1, no traceback, no hang, nothing written.

The cases are the DBC ones of the hostile-input collection (the project's input contract, DESIGN.md: "Bad
input gets a clear message naming file, line and what to do, exit code 1, no traceback, nothing written"):
an attribute value beyond a double (GenMsgCycleTime 1e400, 1e1000000), a signal 10^9 bits long or starting
at bit 4294967295 (cantools never returns on them), a duplicate identifier placed at the second message's
line, a 5,000-digit message identifier (beyond Python's int/str conversion limit), and an endless file.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import cli

from netcfg.commands import main
from netcfg.diagnostics import Collector
from netcfg.importers import ImportOptions
from netcfg.importers.dbc import import_dbc
from netcfg.inputs import MAX_BYTES, InputError

BASE = """VERSION ""

NS_ :

BS_:

BU_: A B

BO_ 256 M1: 8 A
 SG_ s1 : 0|8@1+ (1,0) [0|255] "" B

BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;
BA_DEF_ "Baudrate" INT 0 1000000;
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_DEF_DEF_ "Baudrate" 500000;
BA_ "Baudrate" 500000;
BA_ "GenMsgCycleTime" BO_ 256 10;
"""

# case -> (text replaced, replacement, line of the error, its column, words the message must have)
CASES = {
    "cycle_time_1e400": ("BO_ 256 10;", "BO_ 256 1e400;", 17, None, "out of range"),
    "cycle_time_1e1000000": ("BO_ 256 10;", "BO_ 256 1e1000000;", 17, None, "out of range"),
    "signal_10e9_bits": ("0|8@1+", "0|1000000000@1+", 10, 13, "1000000000 bits"),
    "signal_start_2e32": ("0|8@1+", "4294967295|8@1+", 10, 11, "starts at bit 4294967295"),
    "id_5000_digits": ("BO_ 256 M1", "BO_ " + "9" * 5000 + " M1", 9, 5, "5000 digits"),
}


def write(tmp_path: Path, case: str) -> Path:
    old, new, *_ = CASES[case]
    path = tmp_path / f"{case}.dbc"
    path.write_text(BASE.replace(old, new, 1), encoding="cp1252")
    return path


@pytest.mark.parametrize("case", sorted(CASES))
def test_hostile_dbc_is_an_error_at_its_line(tmp_path: Path, case: str, capsys: pytest.CaptureFixture[str]) -> None:
    """Through the command line's own entry point (in this process: the cases are many, a process each is slow;
    the endless-file case below runs the real process)."""
    _, _, line, column, words = CASES[case]
    path = write(tmp_path, case)
    out = tmp_path / "out.yaml"
    for argv in (["check", str(path)], ["import", "dbc", str(path), "-o", str(out)]):
        assert main(argv) == 1
        err = capsys.readouterr().err
        assert "Traceback" not in err and "internal error" not in err
        where = f"{path}:{line}:" + (f"{column}:" if column else "")
        errors = [x for x in err.splitlines() if ": error: " in x]
        assert errors and errors[0].startswith(where), err
        assert words in errors[0]
    assert not out.exists()


def test_duplicate_identifier_is_placed_at_the_second_message(tmp_path: Path) -> None:
    """Two messages with identifier 256; the second is on line 3, and that is where the error points."""
    path = tmp_path / "dup.dbc"
    path.write_text(
        'BO_ 256 M: 8 A\n SG_ s : 0|8@1+ (1,0) [0|255] "" B\nBO_ 256 N: 8 A\n SG_ t : 0|8@1+ (1,0) [0|255] "" B\n',
        encoding="cp1252",
    )
    proc = cli("check", str(path), "--bitrate", "500k", cwd=tmp_path)
    assert proc.returncode == 1
    errors = [x for x in proc.stderr.splitlines() if ": error: " in x]
    assert errors and errors[0].startswith(f"{path}:3:") and "duplicate-id" in errors[0], proc.stderr


def test_an_endless_file_is_refused_before_it_is_read_whole(tmp_path: Path) -> None:
    """/dev/zero as a DBC: the one input guard refuses a device before reading it and a file over the DBC size limit
    before reading it whole; both are I/O problems (exit 2), nothing is written."""
    zero = Path("/dev/zero")
    if not zero.exists():
        pytest.skip("no /dev/zero here")
    with pytest.raises(InputError, match="not a regular file"):
        import_dbc(zero, ImportOptions(bitrate=500_000), Collector())
    proc = cli("import", "dbc", str(zero), "-o", "out.yaml", cwd=tmp_path)
    assert proc.returncode == 2 and "not a regular file" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "out.yaml").exists()
    big = tmp_path / "big.dbc"
    with big.open("wb") as f:
        f.truncate(MAX_BYTES["DBC"] + 1)  # sparse: no disk space used
    proc = cli("check", str(big), "--bitrate", "500k", cwd=tmp_path)
    assert proc.returncode == 2 and str(big) in proc.stderr and "at most" in proc.stderr, proc.stderr


def test_a_text_where_a_numeric_attribute_belongs_is_an_error_at_its_value(tmp_path: Path) -> None:
    """GenMsgCycleTime is INT (its BA_DEF_), the value "10ms" is text: cantools fails with a bare decimal
    error; netcfg names the attribute, the line (17) and the column of the value (31)."""
    path = tmp_path / "text.dbc"
    path.write_text(BASE.replace("BO_ 256 10;", 'BO_ 256 "10ms";'), encoding="cp1252")
    proc = cli("check", str(path), cwd=tmp_path)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    errors = [x for x in proc.stderr.splitlines() if ": error: " in x]
    assert errors[0].startswith(f"{path}:17:31: error: attribute GenMsgCycleTime is INT"), proc.stderr
