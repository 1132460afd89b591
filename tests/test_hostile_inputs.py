"""Every hostile input found so far, one test each, held to the input contract: a clear message, exit 1 for a bad
input (2 for usage and I/O), no traceback, no hang, nothing written, nothing of the user's touched.

The commands run in-process through netcfg.commands.main, so an exception that escapes fails the test as a traceback
would. The inputs are written here; the DBC-file cases belong to the DBC importer's tests.
"""

from __future__ import annotations

import copy
import json
import os
import stat
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from conftest import ROOT

from netcfg.commands import main
from netcfg.outputs import MANIFEST, MARKER, OLD_TAG, TMP_TAG

GENERATED = ROOT / "generated"

MINI = """\
system: mini
buses:
  - {name: can0, protocol: can, bitrate: 500 kbit/s}
nodes:
  - {name: a, buses: [can0]}
  - {name: b, buses: [can0]}
messages:
  - {name: m1, producer: a, consumers: [b], id: 0x100, size: SIZE, period: 10 ms}
"""

# A minimal CiA 306 EDS: device type, error register, identity (RECORD), TPDO1 mapping 0x6064 (position actual value)
EDS = """\
[FileInfo]
FileName=dev.eds
EDSVersion=4.0

[DeviceInfo]
VendorName=Acme
VendorNumber=0x1234
ProductName=Widget
ProductNumber=1
RevisionNumber=1
BaudRate_1000=1
SimpleBootUpSlave=1
Granularity=8
NrOfRXPDO=0
NrOfTXPDO=1

[MandatoryObjects]
SupportedObjects=3
1=0x1000
2=0x1001
3=0x1018

[OptionalObjects]
SupportedObjects=3
1=0x1800
2=0x1A00
3=0x6064

[1000]
ParameterName=Device type
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=0x00020192
PDOMapping=0

[1001]
ParameterName=Error register
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=0
PDOMapping=0

[1018]
ParameterName=Identity object
ObjectType=0x9
SubNumber=2

[1018sub0]
ParameterName=Number of entries
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=1
PDOMapping=0

[1018sub1]
ParameterName=Vendor-ID
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=0x1234
PDOMapping=0

[1800]
ParameterName=TPDO1 communication parameter
ObjectType=0x9
SubNumber=3

[1800sub0]
ParameterName=Highest sub-index supported
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=2
PDOMapping=0

[1800sub1]
ParameterName=COB-ID
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=$NODEID+0x180
PDOMapping=0

[1800sub2]
ParameterName=Transmission type
ObjectType=0x7
DataType=0x0005
AccessType=rw
DefaultValue=1
PDOMapping=0

[1A00]
ParameterName=TPDO1 mapping parameter
ObjectType=0x9
SubNumber=2

[1A00sub0]
ParameterName=Number of mapped objects
ObjectType=0x7
DataType=0x0005
AccessType=rw
DefaultValue=1
PDOMapping=0

[1A00sub1]
ParameterName=Mapped object 1
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0x60640020
PDOMapping=0

[6064]
ParameterName=Position actual value
ObjectType=0x7
DataType=0x0004
AccessType=ro
DefaultValue=0
PDOMapping=1
"""

EDS_SPEC = """\
system: edsmini
buses:
  - name: can0
    protocol: canopen
    bitrate: 1 Mbit/s
    canopen: {sync_period: 20 ms}
nodes:
  - {name: master, role: master, node_id: 127, buses: [can0]}
  - {name: drive, node_id: 1, device: {eds: EDSPATH}, buses: [can0]}
messages:
  - name: drive_state
    producer: drive
    consumers: [master]
    pdo: {tpdo: 1, transmission: 1, map: [0x6064]}
"""

DBC = """\
VERSION ""

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

BIG = "9" * 5000


def run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    """-> (exit code, stderr) of `netcfg ARGS` in this process; argparse's usage errors exit 2."""
    try:
        rc = main(list(args))
    except SystemExit as exc:
        rc = exc.code if isinstance(exc.code, int) else 2
    _, err = capsys.readouterr()
    assert "Traceback" not in err and "internal error" not in err, err
    return rc, err


def snapshot(folder: Path) -> dict[str, bytes | str]:
    """Every file (its bytes) and symlink (its target) under folder, to show that nothing was touched."""
    out: dict[str, bytes | str] = {}
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder).as_posix()
        if p.is_symlink():
            out[rel] = "-> " + os.readlink(p)
        elif p.is_file():
            out[rel] = p.read_bytes()
        else:
            out[rel + "/"] = ""
    return out


@pytest.fixture
def proj(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A project folder holding the mini spec; the current folder while the test runs."""
    folder = tmp_path / "proj"
    folder.mkdir()
    (folder / "spec.yaml").write_text(MINI.replace("SIZE", "8"))
    monkeypatch.chdir(folder)
    return folder


def eds_spec(folder: Path, eds_text: str | bytes, name: str = "dev.eds") -> Path:
    path = folder / name
    if isinstance(eds_text, str):
        path.write_text(eds_text)
    else:
        path.write_bytes(eds_text)
    spec = folder / "spec.yaml"
    spec.write_text(EDS_SPEC.replace("EDSPATH", name))
    return spec


# --- the output folder -------------------------------------------------------------------------------------------


def test_01_the_spec_folder_is_refused(proj: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (proj / "notes.txt").write_text("mine")
    before = snapshot(proj)
    rc, err = run(capsys, "build", "spec.yaml", "-o", str(proj / "sub" / ".."))
    assert rc == 2 and "current folder" in err
    os.chdir(proj.parent)
    rc, err = run(capsys, "build", "proj/spec.yaml", "-o", "proj")
    assert rc == 2 and "proj" in err
    assert snapshot(proj) == before


def test_01_a_netcfg_folder_holding_the_spec_is_refused(proj: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run(capsys, "build", "spec.yaml", "-o", "out")[0] == 0
    (proj / "out" / "spec.yaml").write_text(MINI.replace("SIZE", "8"))
    before = snapshot(proj)
    rc, err = run(capsys, "build", "out/spec.yaml", "-o", "out")
    assert rc == 2 and "holds the input" in err
    assert snapshot(proj) == before


@pytest.mark.parametrize("target", [".", "CWD"])
def test_02_the_current_folder_is_refused(proj: Path, capsys: pytest.CaptureFixture[str], target: str) -> None:
    before = snapshot(proj)
    rc, err = run(capsys, "build", "spec.yaml", "-o", str(proj) if target == "CWD" else target)
    assert rc == 2 and "current folder" in err
    assert snapshot(proj) == before


def test_03_a_user_folder_at_the_default_output_is_refused(proj: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (proj / "generated" / "mini").mkdir(parents=True)
    (proj / "generated" / "mini" / "handwritten.c").write_text("int main(void) { return 0; }\n")
    before = snapshot(proj)
    rc, err = run(capsys, "build", "spec.yaml")
    assert rc == 2 and "generated/mini" in err and "did not write" in err
    assert snapshot(proj) == before


def test_03_a_rebuild_replaces_what_the_manifest_lists_and_keeps_the_users_files(
    proj: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The manifest-driven rebuild: a header of a node the spec no longer has goes, the user's files stay."""
    three = MINI.replace("SIZE", "8").replace("  - {name: b, buses: [can0]}\n", "  - {name: b, buses: [can0]}\n"
                                               "  - {name: c, buses: [can0]}\n")
    three += "  - {name: m2, producer: c, consumers: [a], id: 0x101, size: 2, period: 10 ms}\n"
    (proj / "spec.yaml").write_text(three)
    assert run(capsys, "build", "spec.yaml")[0] == 0
    out = proj / "generated" / "mini"
    manifest = json.loads((out / MANIFEST).read_text())
    assert "c/c.h" in manifest["files"] and (out / "c" / "c.h").is_file()
    (out / "handwritten.c").write_text("int main(void) { return 0; }\n")
    (out / "c" / "notes.txt").write_text("mine")
    (out / "mine").mkdir()
    (proj / "spec.yaml").write_text(MINI.replace("SIZE", "8"))
    rc, err = run(capsys, "build", "spec.yaml")
    assert rc == 0
    assert "handwritten.c" in err and "c/notes.txt" in err  # named in the warning
    assert (out / "handwritten.c").read_text() == "int main(void) { return 0; }\n"
    assert (out / "c" / "notes.txt").read_text() == "mine" and (out / "mine").is_dir()
    assert not (out / "c" / "c.h").exists()
    assert "c/c.h" not in json.loads((out / MANIFEST).read_text())["files"]


def test_03_the_user_file_at_a_path_the_build_writes_is_refused(proj: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run(capsys, "build", "spec.yaml", "-o", "out")[0] == 0
    manifest = json.loads((proj / "out" / MANIFEST).read_text())
    del manifest["files"]["report.md"]  # as if an older build had not written it: the user's file now
    (proj / "out" / MANIFEST).write_text(json.dumps(manifest))
    (proj / "out" / "report.md").write_text("my notes")
    rc, err = run(capsys, "build", "spec.yaml", "-o", "out")
    assert rc == 2 and "report.md" in err
    assert (proj / "out" / "report.md").read_text() == "my notes"


def test_04_only_marked_leftovers_beside_the_output_are_removed(proj: Path, capsys: pytest.CaptureFixture[str]) -> None:
    users = [proj / ".out.backup.tmp", proj / ".out.old", proj / f".out{TMP_TAG}mine", proj / f".out{OLD_TAG}"]
    for folder in users:
        folder.mkdir()
        (folder / "keep.txt").write_text("keep")
    leftover = proj / f".out{TMP_TAG}dead"  # what a killed build leaves: carries the marker
    leftover.mkdir()
    (leftover / MARKER).write_text("")
    (leftover / "runtime.json").write_text("{}")
    assert run(capsys, "build", "spec.yaml", "-o", "out")[0] == 0
    assert all((folder / "keep.txt").read_text() == "keep" for folder in users)
    assert not leftover.exists()


def test_04_a_backup_left_by_a_killed_build_is_restored(proj: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Killed between its two renames, a build leaves the old tree as the marked backup and no output folder."""
    assert run(capsys, "build", "spec.yaml", "-o", "out")[0] == 0
    (proj / "out" / "mine.txt").write_text("mine")
    (proj / "out" / MARKER).write_text("")
    os.rename(proj / "out", proj / f".out{OLD_TAG}")
    assert run(capsys, "build", "spec.yaml", "-o", "out")[0] == 0
    assert (proj / "out" / "mine.txt").read_text() == "mine"
    assert not (proj / f".out{OLD_TAG}").exists() and not (proj / "out" / MARKER).exists()


def test_05_a_file_as_output_folder_is_refused(proj: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (proj / "out.txt").write_text("precious")
    before = snapshot(proj)
    for _ in range(2):
        rc, err = run(capsys, "build", "spec.yaml", "-o", "out.txt")
        assert rc == 2 and "is a file" in err
    assert snapshot(proj) == before


def test_06_a_symlink_is_followed_and_judged_by_its_target(proj: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (proj / "real").mkdir()
    (proj / "real" / "k.txt").write_text("keep")
    (proj / "link").symlink_to("real")
    before = snapshot(proj)
    rc, err = run(capsys, "build", "spec.yaml", "-o", "link")
    assert rc == 2 and "did not write" in err
    assert snapshot(proj) == before
    (proj / "empty").mkdir()
    (proj / "elink").symlink_to("empty")
    for _ in range(2):  # repeated builds through the link keep working
        assert run(capsys, "build", "spec.yaml", "-o", "elink")[0] == 0
        assert (proj / "elink").is_symlink() and (proj / "empty" / "runtime.json").is_file()


def test_25_output_folders_follow_the_umask(proj: Path, capsys: pytest.CaptureFixture[str]) -> None:
    old = os.umask(0o022)
    try:
        assert run(capsys, "build", "spec.yaml", "-o", "deep/out")[0] == 0
    finally:
        os.umask(old)
    for folder in (proj / "deep", proj / "deep" / "out", proj / "deep" / "out" / "c"):
        assert stat.S_IMODE(folder.stat().st_mode) == 0o755, folder


def test_concurrent_builds_leave_one_whole_tree(proj: Path) -> None:
    """Two builds of different specs into one folder at once: the lock on the parent serialises the swaps, so the
    result is one build's tree exactly (the manifest matches every file) and no temporary is left."""
    import hashlib
    import subprocess
    import sys

    (proj / "other.yaml").write_text(MINI.replace("SIZE", "4"))
    procs = [
        subprocess.Popen([sys.executable, "-m", "netcfg", "build", spec, "-o", "out"], cwd=proj,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        for spec in ("spec.yaml", "other.yaml", "spec.yaml", "other.yaml")
    ]
    assert [p.wait(timeout=120) for p in procs] == [0, 0, 0, 0]
    manifest = json.loads((proj / "out" / MANIFEST).read_text())
    files = {p.relative_to(proj / "out").as_posix() for p in (proj / "out").rglob("*") if p.is_file()}
    assert files == set(manifest["files"]) | {MANIFEST}
    for rel, digest in manifest["files"].items():
        assert hashlib.sha256((proj / "out" / rel).read_bytes()).hexdigest() == digest
    assert sorted(p.name for p in proj.iterdir()) == ["other.yaml", "out", "spec.yaml"]


def test_the_committed_generated_folders_carry_manifests() -> None:
    for folder in sorted(p for p in GENERATED.iterdir() if p.is_dir()):
        listed = set(json.loads((folder / MANIFEST).read_text())["files"])
        present = {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()} - {MANIFEST}
        assert listed == present, folder.name


# --- import commands ---------------------------------------------------------------------------------------------


def test_24_a_failed_import_leaves_no_temporary(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "a.dbc").write_text(DBC)
    (tmp_path / "out.yaml").mkdir()
    before = snapshot(tmp_path)
    rc, err = run(capsys, "import", "dbc", str(tmp_path / "a.dbc"), "-o", str(tmp_path / "out.yaml"))
    assert rc == 2 and "is a folder" in err
    assert snapshot(tmp_path) == before


def test_28_an_import_never_writes_over_its_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "a.dbc").write_text(DBC)
    (tmp_path / "same.dbc").symlink_to("a.dbc")
    for target in ("a.dbc", "same.dbc"):
        rc, err = run(capsys, "import", "dbc", str(tmp_path / "a.dbc"), "-o", str(tmp_path / target))
        assert rc == 2 and "is the input file" in err
    assert (tmp_path / "a.dbc").read_text() == DBC
    rc, _ = run(capsys, "import", "dbc", str(tmp_path / "a.dbc"), "-o", str(tmp_path / "a.yaml"))
    assert rc == 0 and sorted(p.name for p in tmp_path.iterdir()) == ["a.dbc", "a.yaml", "same.dbc"]


# --- the spec ----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "value", ["!!int abc", "!!float x", "!!bool maybe", "!!int 0x", "!!set {a, b}", '!!binary "%%%"',
              '!!python/object/apply:os.system ["true"]', BIG, "1" + "0" * 60 + ".5"],
    ids=["int-abc", "float-x", "bool-maybe", "int-0x", "set", "binary", "python", "5000-digits", "long-float"],
)
def test_07_29_a_bad_value_is_an_error_at_its_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                   value: str) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text(MINI.replace("SIZE", value))
    rc, err = run(capsys, "check", str(spec))
    assert rc == 1 and f"{spec}:8:" in err


@pytest.mark.parametrize(
    ("field", "text"),
    [("period: 10 ms", "period: 1e1000000 ms"), ("period: 10 ms", "rate: 1e999999999 Hz"),
     ("period: 10 ms", "period: 1e-1000000 ms"), ("period: 10 ms", f"period: {BIG} ms")],
    ids=["huge-exponent", "huge-rate", "tiny-exponent", "5000-digit-period"],
)
def test_10_11_an_extreme_quantity_is_an_error_at_its_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], field: str, text: str
) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text(MINI.replace("SIZE", "8").replace(field, text))
    rc, err = run(capsys, "check", str(spec))
    assert rc == 1 and f"{spec}:8:" in err and "range" in err


def test_deep_nesting_is_refused_before_parsing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text("system: t\ndescription: " + "[" * 25_000 + "]" * 25_000 + "\n")
    rc, err = run(capsys, "check", str(spec))
    assert rc == 1 and "nested more than" in err and f"{spec}:2:" in err


# --- device files ------------------------------------------------------------------------------------------------


def test_18_identity_as_a_var_names_the_object(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    var = EDS.replace("[1018]\nParameterName=Identity object\nObjectType=0x9\nSubNumber=2",
                      "[1018]\nParameterName=Identity object\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\n"
                      "DefaultValue=0\nPDOMapping=0")
    var = var.split("[1018sub0]")[0] + "[1800]" + var.split("[1800]", 1)[1]
    spec = eds_spec(tmp_path, var)
    rc, err = run(capsys, "check", str(spec))
    assert rc == 1 and "0x1018" in err and "is a VAR" in err and f"{spec}:9:" in err


def test_19_a_negative_vendor_id_is_refused_and_nothing_written(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    spec = eds_spec(tmp_path, EDS.replace("DefaultValue=0x1234", "DefaultValue=-5"))
    rc, err = run(capsys, "build", str(spec), "-o", str(tmp_path / "out"))
    assert rc == 1 and "0x1018:1" in err and "UNSIGNED32" in err
    assert not (tmp_path / "out").exists()


def test_19_a_negative_vendor_number_in_device_info_is_refused(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    spec = eds_spec(tmp_path, EDS.replace("VendorNumber=0x1234", "VendorNumber=-5"))
    rc, err = run(capsys, "check", str(spec))
    assert rc == 1 and "VendorNumber=-5" in err


@pytest.mark.parametrize(
    ("damage", "text"),
    [(("[1018sub1]", "[1018sub" + "9" * 5000 + "]"), "outside CiA 301's ranges"),
     (("DefaultValue=0x00020192", "DefaultValue=0x" + "9" * 5000), "more than any CANopen data type holds"),
     (("DefaultValue=0x00020192", "DefaultValue=" + "9" * 5000), "more than 20 digits")],
    ids=["5000-digit-sub-index", "5000-digit-hex-value", "5000-digit-decimal-value"],
)
def test_29_huge_numbers_in_an_eds_name_the_object(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                   damage: tuple[str, str], text: str) -> None:
    """Hex numbers escape Python's 4,300-digit limit on parsing but not on printing; CiA 301's ranges stop them."""
    spec = eds_spec(tmp_path, EDS.replace(*damage))
    rc, err = run(capsys, "check", str(spec))
    assert rc == 1 and text in err and f"{spec}:9:" in err


def test_20_a_nul_byte_in_a_path_is_an_error_at_its_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = eds_spec(tmp_path, EDS)
    spec.write_text(EDS_SPEC.replace("EDSPATH", '"dev\\0.eds"'))
    rc, err = run(capsys, "check", str(spec))
    assert rc == 1 and f"{spec}:9:" in err and "NUL byte" in err


def test_21_a_symlink_loop_is_an_error_at_its_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = eds_spec(tmp_path, EDS)
    (tmp_path / "l1.eds").symlink_to("l2.eds")
    (tmp_path / "l2.eds").symlink_to("l1.eds")
    spec.write_text(EDS_SPEC.replace("EDSPATH", "l1.eds"))
    rc, err = run(capsys, "check", str(spec))
    assert rc == 1 and f"{spec}:9:" in err and "symbolic links" in err


def test_26_an_eds_with_a_byte_order_mark_is_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = eds_spec(tmp_path, b"\xef\xbb\xbf" + EDS.encode())
    assert run(capsys, "check", str(spec))[0] == 0


def test_27_an_eds_in_windows_1252_is_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """CiA 306 files from Windows tools are often cp1252: 0xFC is 'ü', 0xB5 'µ' there (and not valid UTF-8)."""
    from netcfg.devices.eds import import_eds

    text = EDS.replace("VendorName=Acme", "VendorName=Acme Gm\u00fcnd").replace(
        "ParameterName=Vendor-ID", "ParameterName=Vendor-ID (\u00b5s)")
    spec = eds_spec(tmp_path, text.encode("cp1252"))
    assert run(capsys, "check", str(spec))[0] == 0
    assert import_eds(tmp_path / "dev.eds", "dev").objects[(0x1018, 1)].name == "Vendor-ID (\u00b5s)"


# --- bus.yml -----------------------------------------------------------------------------------------------------

BUS_YML = """\
options:
  dcf_path: "."
master:
  node_id: 127
  baudrate: 1000
  sync_period: 20000
drive:
  dcf: "dev.eds"
  node_id: 1
"""


def test_09_a_huge_pdo_mapping_count_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "dev.eds").write_text(EDS.replace("DefaultValue=1\nPDOMapping=0\n\n[1A00sub1]",
                                                  "DefaultValue=0x7FFFFFFF\nPDOMapping=0\n\n[1A00sub1]"))
    (tmp_path / "bus.yml").write_text(BUS_YML)
    rc, err = run(capsys, "import", "bus-yml", str(tmp_path / "bus.yml"), "-o", str(tmp_path / "spec.yaml"))
    assert rc == 1 and "0x1A00:0" in err and "0..64" in err
    line = EDS.splitlines().index("[1A00sub0]") + 1
    assert f"line {line}" in err
    assert not (tmp_path / "spec.yaml").exists()


def test_29_a_5000_digit_baudrate_in_a_bus_yml(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "bus.yml").write_text(f"master:\n  node_id: 127\n  baudrate: {BIG}\n")
    rc, err = run(capsys, "import", "bus-yml", str(tmp_path / "bus.yml"), "-o", str(tmp_path / "o.yaml"))
    assert rc == 1 and "bus.yml:3:" in err
    assert not (tmp_path / "o.yaml").exists()


# --- endless inputs ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("command", [["check"], ["simulate"], ["import", "bus-yml"], ["build"]])
def test_23_dev_zero_is_refused_at_once(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                        command: list[str]) -> None:
    out = ["-o", str(tmp_path / "o.yaml")] if command[0] == "import" else []
    rc, err = run(capsys, *command, "/dev/zero", *out)
    assert rc == 2 and "not a regular file" in err
    assert list(tmp_path.iterdir()) == []


def test_23_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    os.mkfifo(tmp_path / "spec.yaml")
    rc, err = run(capsys, "check", str(tmp_path / "spec.yaml"))
    assert rc == 2 and "not a regular file" in err


def test_an_oversized_input_is_refused_before_reading(tmp_path: Path) -> None:
    from netcfg.inputs import MAX_BYTES, InputError, read_input_text

    big = tmp_path / "big.json"
    with big.open("wb") as f:
        f.truncate(MAX_BYTES["runtime config"] + 1)  # sparse: no disk used
    with pytest.raises(InputError, match="may be at most"):
        read_input_text(big, "runtime config")


# --- runtime.json ------------------------------------------------------------------------------------------------


def runtime_doc(system: str) -> dict[str, Any]:
    doc: dict[str, Any] = json.loads((GENERATED / system / "runtime.json").read_text())
    return doc


def first_can_bus(doc: dict[str, Any]) -> dict[str, Any]:
    return next(b for b in doc["buses"] if b["protocol"] == "canopen")


def first_pdo_message(doc: dict[str, Any]) -> dict[str, Any]:
    return next(m for m in doc["messages"] if m["pdo"] is not None and m["signals"])


E40 = 10**40
DAMAGE: dict[str, tuple[str, Callable[[dict[str, Any]], None], str]] = {
    "12-ec-zero": ("cambada", lambda d: d["buses"][0]["ftt"].update(ec_ns=0), "ec_ns"),
    "12-ec-negative": ("cambada", lambda d: d["buses"][0]["ftt"].update(ec_ns=-5_000_000), "ec_ns"),
    "12-ec-one-ns": ("cambada", lambda d: d["buses"][0]["ftt"].update(ec_ns=1), "elementary cycle"),
    "15-name-null": ("allex2", lambda d: d["messages"][0].update(name=None), "name: must not be null"),
    "15-size-1e40": ("allex2", lambda d: d["messages"][0].update(size=E40), "size"),
    "15-bitrate-zero": ("allex2", lambda d: d["buses"][0].update(bitrate=0), "bitrate"),
    "15-canopen-null": ("allex2", lambda d: first_can_bus(d).update(canopen=None), "needs its 'canopen' section"),
    "16-pdo-entry-1e40-bits": ("allex2", lambda d: first_pdo_message(d)["pdo"]["entries"][0].update(bits=E40),
                               "bits"),
    "16-signal-1e40-bits": ("allex2", lambda d: first_pdo_message(d)["signals"][0].update(bits=E40), "bits"),
    "16-kind-bogus": ("allex2", lambda d: d["messages"][0].update(kind="bogus"), "'bogus' is not one of"),
    "16-protocol-bogus": ("allex2", lambda d: d["buses"][0].update(protocol="bogus"), "'bogus' is not one of"),
    "16-period-zero": ("allex2", lambda d: d["messages"][0].update(period_ns=0), "period_ns"),
    "16-sync-period-zero": ("allex2", lambda d: first_can_bus(d)["canopen"].update(sync_period_ns=0),
                            "sync_period_ns"),
    "16-id-bits-99": ("allex2", lambda d: d["buses"][0].update(id_bits=99), "id_bits"),
    "34-duplicate-node": ("allex2", lambda d: d["nodes"].append(copy.deepcopy(d["nodes"][0])), "duplicate name"),
    "34-duplicate-message": ("allex2", lambda d: d["messages"].append(copy.deepcopy(d["messages"][-1])),
                             "duplicate name"),
    "signal-outside-payload": ("allex2", lambda d: first_pdo_message(d)["signals"][0].update(start_bit=60),
                               "does not fit"),
}


@pytest.mark.parametrize("case", sorted(DAMAGE))
def test_12_15_16_34_a_damaged_runtime_json_is_malformed(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                        case: str) -> None:
    system, damage, text = DAMAGE[case]
    doc = runtime_doc(system)
    damage(doc)
    path = tmp_path / "runtime.json"
    path.write_text(json.dumps(doc))
    rc, err = run(capsys, "simulate", str(path), "--duration", "100ms")
    assert rc == 1 and "malformed runtime config" in err and text in err


def test_08_29_runtime_json_nesting_and_long_integers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "runtime.json"
    path.write_text("[" * 25_000 + "]" * 25_000)
    rc, err = run(capsys, "simulate", str(path))
    assert rc == 1 and "not a runtime config" in err and "nested deeper" in err
    path.write_text(json.dumps(runtime_doc("allex2")).replace('"size": 8', f'"size": {BIG}', 1))
    rc, err = run(capsys, "simulate", str(path))
    assert rc == 1 and "5000 digits" in err


def test_the_emitted_runtime_json_matches_its_schema_strictly() -> None:
    """What the emitter writes and what load() accepts are one table: every committed file passes the strict check
    (no key the table does not know, every range kept)."""
    from netcfg.runtime.schema import MAX_NS, check_document
    from netcfg.spec.units import MAX_DURATION_NS

    assert MAX_NS == MAX_DURATION_NS
    for folder in sorted(p for p in GENERATED.iterdir() if p.is_dir()):
        assert check_document(runtime_doc(folder.name), strict=True) == [], folder.name


# --- simulate options and work limit -----------------------------------------------------------------------------

TASK_1NS = """\
system: taskmini
buses:
  - {name: can0, protocol: can, bitrate: 500 kbit/s}
nodes:
  - name: a
    buses: [can0]
    tasks:
      - {name: t, period: 1 ns, wcet: 1 ns}
  - name: b
    buses: [can0]
    tasks:
      - {name: r, on_message: m1, wcet: 1 us}
messages:
  - {name: m1, producer: a, consumers: [b], id: 0x100, size: 8, period: 10 ms}
flows:
  - {name: f, chain: [a.t, m1, b.r]}
"""


def test_13_a_1ns_task_is_refused_by_the_work_limit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """1 s of a 1 ns task is 10^9 task jobs (10^9 ns / 1 ns), beyond the default limit of 2 * 10^7 events."""
    spec = tmp_path / "spec.yaml"
    spec.write_text(TASK_1NS)
    rc, err = run(capsys, "simulate", str(spec), "--duration", "1s")
    assert rc == 2 and "task 'a.t'" in err and "1,000,000,000 per simulated second" in err and "--max-events" in err


def test_work_estimate_counts_every_source() -> None:
    """The estimate is, per simulated second, 10^9 / period (or minimum inter-arrival) of every message plus one
    event per SYNC: here recomputed from the configuration's own periods. allex2's SYNC period is 20 ms (seed 000),
    so the SYNC source alone is 50 per second."""
    from fractions import Fraction

    from netcfg import runtime
    from netcfg.sim.limits import events_per_second

    cfg = runtime.load(GENERATED / "allex2" / "runtime.json")
    rates = events_per_second(cfg)
    expected = sum((Fraction(10**9, m.period_ns or m.interval_ns or 1) for m in cfg.messages
                    if m.period_ns or m.interval_ns), Fraction(0))
    expected += sum(Fraction(10**9, b.canopen.sync_period_ns) for b in cfg.buses if b.canopen is not None)
    assert sum(r for k, r in rates.items() if not k.startswith("task")) == expected
    assert rates["SYNC of bus 'can0'"] == 50  # 20 ms SYNC period (seed 000)


@pytest.mark.parametrize(
    ("args", "text"),
    [
        (["--duration", "1000000000s"], "longer than netcfg handles"),
        (["--duration", "0s"], "above 0"),
        (["--duration", "1e1000000 s"], "out of range"),
        (["--runs", "2", "--jobs", "0"], "--jobs"),
        (["--runs", "2", "--jobs", "-1"], "--jobs"),
        (["--runs", "\u0662"], "--runs"),
        (["--seed", BIG], "--seed"),
        (["--drift", "nan"], "--drift"),
        (["--max-events", "0"], "--max-events"),
        (["--fault", "ber=0.5"], "bus-off"),
    ],
    ids=["duration-huge", "duration-zero", "duration-exponent", "jobs-0", "jobs-negative", "runs-arabic",
         "seed-5000-digits", "drift-nan", "max-events-0", "ber-half"],
)
def test_14_17_33_simulate_options_out_of_range_are_usage_errors(
    capsys: pytest.CaptureFixture[str], args: list[str], text: str
) -> None:
    rc, err = run(capsys, "simulate", str(GENERATED / "allex2" / "runtime.json"), *args)
    assert rc == 2 and text in err


def test_17_the_bit_error_limit_is_fault_confinements_one_in_nine() -> None:
    """A frame fails when any of its L bits is hit: 1 - (1 - ber)^L. ISO 11898-1's error counter (+8 per failed
    frame, -1 per good one) grows without bound beyond 1 failure in 9 frames. For the longest frame of allex2
    (8 data bytes, 11-bit id, worst-case stuffing: 135 bits, CiA's figure): ber 1e-4 fails 1.3 % (accepted),
    1e-3 fails 12.6 % (refused)."""
    from netcfg import runtime
    from netcfg.sim.faults import Fault
    from netcfg.sim.limits import fault_problem
    from netcfg.timing.frames import can_frame_bits

    assert can_frame_bits(8, False, "worst") == 135
    cfg = runtime.load(GENERATED / "allex2" / "runtime.json")
    assert fault_problem(cfg, (Fault.parse("ber=1e-4"),)) is None
    problem = fault_problem(cfg, (Fault.parse("ber=1e-3"),))
    assert problem is not None and "13%" in problem


@pytest.mark.parametrize("rate", ["\u0665\u0660\u0660k", "\uff15\uff10\uff10k", "1e1000000 kbit/s", "infk", "0"])
def test_32_bitrate_option_takes_ascii_digits_only(capsys: pytest.CaptureFixture[str], rate: str) -> None:
    rc, err = run(capsys, "check", str(ROOT / "specs" / "cambada.yaml"), "--bitrate", rate)
    assert rc == 2 and "is not a bit rate" in err
