"""`netcfg lsp` driven by a real LSP client (pytest-lsp's, which also checks the server keeps to the protocol),
with the server started as a subprocess the way an editor starts it.

The expected figures are always `netcfg check`'s own for the same text: the server must say what check says, at
the same place (check's lines and columns are 1-based, LSP's 0-based). Positions in the specs are found by
searching their text, so the tests name what they look at rather than a line number.
"""

from __future__ import annotations

import asyncio
import json
import shutil
import subprocess
import sys
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from lsprotocol import types as lsp
from pytest_lsp import LanguageClient, client_capabilities, make_test_lsp_client

from netcfg.report_text import num
from tests.conftest import EPOS4_EDS, ROOT, SPECS, cli

ALLEX2 = SPECS / "allex2.yaml"
SERVER = ["-m", "netcfg", "lsp"]


def run(body: Callable[[LanguageClient], Awaitable[None]]) -> None:
    """Start `netcfg lsp`, initialise a session, run body, shut the server down."""

    async def main() -> None:
        client = make_test_lsp_client()
        published: list[lsp.PublishDiagnosticsParams] = []
        client.published = published  # type: ignore[attr-defined]

        features = client.protocol.fm.features
        theirs = features[lsp.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS]

        def collect(params: lsp.PublishDiagnosticsParams) -> None:  # every one, none lost between two waits
            published.append(params)
            theirs(params)

        features[lsp.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS] = collect

        await client.start_io(sys.executable, *SERVER)
        try:
            await client.initialize_session(
                lsp.InitializeParams(capabilities=client_capabilities("visual-studio-code"))
            )
            await asyncio.wait_for(body(client), 90)
            await client.shutdown_session()
        except BaseException:
            if client._server is not None and client._server.returncode is None:
                client._server.kill()  # a failed test must not wait for a server that was never told to exit
            raise
        finally:
            await client.stop()

    asyncio.run(main())


async def open_and_wait(client: LanguageClient, path: Path, text: str, version: int = 1) -> list[lsp.Diagnostic]:
    """Open a spec with this text; the diagnostics the server publishes for this version of it."""
    uri = path.resolve().as_uri()
    client.text_document_did_open(lsp.DidOpenTextDocumentParams(lsp.TextDocumentItem(uri, "yaml", version, text)))
    return await diagnostics_of(client, uri, version)


async def diagnostics_of(client: LanguageClient, uri: str, version: int) -> list[lsp.Diagnostic]:
    return list((await published_for(client, lambda p: p.uri == uri and p.version == version)).diagnostics)


async def published_for(
    client: LanguageClient, wanted: Callable[[lsp.PublishDiagnosticsParams], bool]
) -> lsp.PublishDiagnosticsParams:
    """The first diagnostics published (since the session began) that are wanted; waits for them."""
    seen = 0
    while True:
        published: list[lsp.PublishDiagnosticsParams] = client.published  # type: ignore[attr-defined]
        for params in published[seen:]:
            if wanted(params):
                published.remove(params)
                return params
        seen = len(published)
        await asyncio.sleep(0.005)


def line_of(text: str, needle: str, nth: int = 0) -> tuple[int, int]:
    """(0-based line, column) of the nth occurrence of needle in text."""
    hits = [(i, line.index(needle)) for i, line in enumerate(text.splitlines()) if needle in line]
    return hits[nth]


def doc(path: Path) -> lsp.TextDocumentIdentifier:
    return lsp.TextDocumentIdentifier(path.resolve().as_uri())


def check_json(path: Path) -> dict[str, Any]:
    proc = cli("check", str(path), "--format", "json")
    report: dict[str, Any] = json.loads(proc.stdout)
    return report


def misspelt(tmp_path: Path) -> tuple[Path, str]:
    """ALLEX-2 with the period of hip_l_cmd written 'perod' (a dropped letter), saved so check can read it too."""
    text = ALLEX2.read_text(encoding="utf-8")
    row, _ = line_of(text, "- name: hip_l_cmd")
    lines = text.splitlines(keepends=True)
    assert lines[row + 3].strip() == "period: 20 ms"
    lines[row + 3] = lines[row + 3].replace("period:", "perod:")
    path = tmp_path / "allex2.yaml"
    path.write_text("".join(lines), encoding="utf-8")
    return path, "".join(lines)


def test_the_seed_specs_have_no_diagnostics() -> None:
    """check accepts both seeds without a warning (tests/test_seeds.py), so the server publishes nothing."""

    async def body(client: LanguageClient) -> None:
        for name in ("allex2.yaml", "cambada.yaml"):
            path = SPECS / name
            assert await open_and_wait(client, path, path.read_text(encoding="utf-8")) == []

    run(body)


def test_a_misspelt_key_is_where_check_puts_it(tmp_path: Path) -> None:
    path, text = misspelt(tmp_path)
    expected = check_json(path)["errors"]
    assert [e["code"] for e in expected] == ["extra-forbidden"]  # one mistake, one error

    async def body(client: LanguageClient) -> None:
        got = await open_and_wait(client, path, text)
        assert [(d.code, d.range.start.line, d.range.start.character, d.message) for d in got] == [
            (e["code"], e["line"] - 1, e["column"] - 1, e["message"]) for e in expected
        ]
        assert got[0].severity == lsp.DiagnosticSeverity.Error
        row, col = line_of(text, "perod:")
        assert (got[0].range.start.line, got[0].range.start.character) == (row, col)  # the key itself
        assert got[0].range.end.character == col + len("perod")

    run(body)


def test_diagnostics_follow_the_editors_text_not_the_file(tmp_path: Path) -> None:
    """The file on disk is correct; the editor's unsaved text has the mistake, then has it fixed."""
    path = tmp_path / "allex2.yaml"
    shutil.copy(ALLEX2, path)
    _, wrong = misspelt(tmp_path / "..")  # the misspelt text, saved elsewhere
    good = ALLEX2.read_text(encoding="utf-8")

    async def body(client: LanguageClient) -> None:
        assert await open_and_wait(client, path, wrong) != []
        client.text_document_did_change(lsp.DidChangeTextDocumentParams(
            lsp.VersionedTextDocumentIdentifier(uri=path.resolve().as_uri(), version=2),
            [lsp.TextDocumentContentChangeWholeDocument(good)],
        ))
        assert await diagnostics_of(client, path.resolve().as_uri(), 2) == []

    run(body)


def test_hover_on_a_message_gives_checks_response_time() -> None:
    text = ALLEX2.read_text(encoding="utf-8")
    report = check_json(ALLEX2)
    (m,) = [m for b in report["buses"] for m in b["messages"] if m["name"] == "hip_l_cmd"]

    async def body(client: LanguageClient) -> None:
        await open_and_wait(client, ALLEX2, text)
        row, col = line_of(text, "- name: hip_l_cmd")
        hover = await client.text_document_hover_async(
            lsp.HoverParams(doc(ALLEX2), lsp.Position(row, col + len("- name: hi")))
        )
        assert hover is not None
        value = hover.contents.value  # type: ignore[union-attr]
        # check's text table prints the bound as num(wcrt_us): 11,224.5 for this message
        assert f"worst-case response time: {num(m['wcrt_us'])} us" in value, value
        assert f"deadline: {num(m['deadline_us'])} us, slack {num(m['slack_us'])} us" in value
        assert f"{m['utilization']:.2%}" in value

        # a flow of CAMBADA: its synchronised and unsynchronised bounds, as check reports them
        cambada = SPECS / "cambada.yaml"
        ctext = cambada.read_text(encoding="utf-8")
        (flow,) = [f for f in check_json(cambada)["flows"] if f["name"] == "motion"]
        await open_and_wait(client, cambada, ctext)
        row, col = line_of(ctext, "- name: motion")
        hover = await client.text_document_hover_async(lsp.HoverParams(doc(cambada), lsp.Position(row, col + 9)))
        assert hover is not None
        value = hover.contents.value  # type: ignore[union-attr]
        u, s = flow["unsynchronised"], flow["synchronised"]
        assert f"synchronised: {num(s['latency_min_us'])} .. {num(s['latency_max_us'])} us" in value, value
        assert f"unsynchronised: {num(u['latency_min_us'])} .. {num(u['latency_max_us'])} us" in value, value

    run(body)


def test_definition_of_a_consumer_is_the_nodes_line() -> None:
    text = ALLEX2.read_text(encoding="utf-8")

    async def body(client: LanguageClient) -> None:
        await open_and_wait(client, ALLEX2, text)
        row, col = line_of(text, "consumers: [knee_l]")
        got = await client.text_document_definition_async(
            lsp.DefinitionParams(doc(ALLEX2), lsp.Position(row, col + len("consumers: [kn")))
        )
        assert isinstance(got, lsp.Location), got
        node_row, node_col = line_of(text, "- name: knee_l")
        assert got.uri == ALLEX2.resolve().as_uri()
        assert (got.range.start.line, got.range.start.character) == (node_row, node_col + len("- name: "))

        # a flow step that is a task goes to the task's name in its node
        cambada = SPECS / "cambada.yaml"
        ctext = cambada.read_text(encoding="utf-8")
        await open_and_wait(client, cambada, ctext)
        row, col = line_of(ctext, "- holonomic.convert")
        got = await client.text_document_definition_async(
            lsp.DefinitionParams(doc(cambada), lsp.Position(row, col + 5))
        )
        assert isinstance(got, lsp.Location), got
        lines = ctext.splitlines()
        assert lines[got.range.start.line][got.range.start.character:].startswith("convert")

    run(body)


def test_completion_offers_a_messages_keys_and_the_specs_node_names() -> None:
    text = ALLEX2.read_text(encoding="utf-8")
    row, _ = line_of(text, "- name: hip_l_interp")
    lines = text.splitlines()
    lines.insert(row + 1, "    ")  # a new, empty line inside the message's mapping
    edited = "\n".join(lines) + "\n"

    async def body(client: LanguageClient) -> None:
        path = ALLEX2
        await open_and_wait(client, path, edited)
        got = await client.text_document_completion_async(lsp.CompletionParams(doc(path), lsp.Position(row + 1, 4)))
        labels = {i.label for i in (got.items if isinstance(got, lsp.CompletionList) else got or [])}
        assert {"period", "deadline", "consumers"} <= labels, labels  # netcfg.spec.schema.Message's fields
        assert "sync_period" not in labels  # a bus's CANopen key, not a message's

        crow, ccol = line_of(edited, "consumers: [hip_l]")
        got = await client.text_document_completion_async(
            lsp.CompletionParams(doc(path), lsp.Position(crow, ccol + len("consumers: [")))
        )
        labels = {i.label for i in (got.items if isinstance(got, lsp.CompletionList) else got or [])}
        assert {"master", "hip_l", "ankle_r"} <= labels  # the spec's nodes
        assert "hip_l_cmd" not in labels  # a message is no consumer

    run(body)


async def fix_with_code_action(client: LanguageClient, path: Path, text: str, diag: lsp.Diagnostic) -> str:
    actions = await client.text_document_code_action_async(lsp.CodeActionParams(
        doc(path), diag.range, lsp.CodeActionContext(diagnostics=[diag])
    ))
    assert actions, "no code action for a did-you-mean"
    (action,) = actions
    assert isinstance(action, lsp.CodeAction) and action.edit and action.edit.changes
    (edit,) = action.edit.changes[path.resolve().as_uri()]
    lines = text.splitlines(keepends=True)
    line = lines[edit.range.start.line]
    lines[edit.range.start.line] = line[: edit.range.start.character] + edit.new_text + line[edit.range.end.character:]
    return "".join(lines)


def test_a_code_action_fixes_a_did_you_mean(tmp_path: Path) -> None:
    path, text = misspelt(tmp_path)
    # a consumer misspelt inside a bracketed list: check places it at the list item, the fix replaces that word
    wrong_node = ALLEX2.read_text(encoding="utf-8").replace("consumers: [knee_l]", "consumers: [kne_l]", 1)
    other = tmp_path / "node.yaml"
    other.write_text(wrong_node, encoding="utf-8")
    (expected,) = check_json(other)["errors"]
    assert "did you mean 'knee_l'?" in expected["message"]

    async def body(client: LanguageClient) -> None:
        (diag,) = await open_and_wait(client, path, text)
        assert "did you mean 'period'?" in diag.message
        fixed = await fix_with_code_action(client, path, text, diag)
        assert fixed == ALLEX2.read_text(encoding="utf-8")

        (diag,) = await open_and_wait(client, other, wrong_node)
        fixed = await fix_with_code_action(client, other, wrong_node, diag)
        assert fixed == ALLEX2.read_text(encoding="utf-8")

    run(body)


def test_an_eds_error_goes_to_the_eds(tmp_path: Path, needs_shared: None) -> None:
    """The EPOS4 EDS with the DataType of [6064] written 0xZZ (as tests/test_error_messages.py): check places the
    error at that line of the EDS, so the server publishes it to the EDS's URI, and nothing on the spec."""
    lines = EPOS4_EDS.read_text(encoding="latin-1").splitlines(keepends=True)
    at = next(i for i, line in enumerate(lines) if line.strip() == "[6064]") + 3
    lines[at] = "DataType=0xZZ\n"
    eds = tmp_path / "drive.eds"
    eds.write_text("".join(lines), encoding="latin-1")
    text = ALLEX2.read_text(encoding="utf-8").replace("device: epos4", "device: {eds: drive.eds}", 1)
    path = tmp_path / "allex2.yaml"
    path.write_text(text, encoding="utf-8")
    (expected,) = check_json(path)["errors"]

    async def body(client: LanguageClient) -> None:
        uri = path.resolve().as_uri()
        client.text_document_did_open(lsp.DidOpenTextDocumentParams(lsp.TextDocumentItem(uri, "yaml", 1, text)))
        published: dict[str, list[lsp.Diagnostic]] = {}
        for target in (uri, eds.resolve().as_uri()):
            published[target] = list((await published_for(client, lambda p, t=target: p.uri == t)).diagnostics)
        assert published[uri] == []
        (diag,) = published[eds.resolve().as_uri()]
        assert (diag.code, diag.range.start.line, diag.range.start.character) == (
            "eds-invalid", expected["line"] - 1, expected["column"] - 1
        )
        assert expected["line"] == at + 1

        # definition of the `eds:` value opens the file
        row, col = line_of(text, "eds: drive.eds")
        got = await client.text_document_definition_async(
            lsp.DefinitionParams(doc(path), lsp.Position(row, col + len("eds: dr")))
        )
        assert isinstance(got, lsp.Location) and got.uri == eds.resolve().as_uri()

    run(body)


def rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise AssertionError("no VmRSS")


def test_edits_in_a_row_are_checked_newest_first_and_keep_memory_flat() -> None:
    """1,000 edits of one spec (its description alternating between two texts), sent in bursts of 50 without waiting.
    The server must end on the last version of each burst and check fewer versions than it was sent (edits that
    arrive during a check are dropped for the newest), and its resident memory after the 1,000 may exceed what it
    was after the first burst by at most 30 MB (a leak of one spec's model per check, ~0.5 MB, would be 500 MB)."""
    text = ALLEX2.read_text(encoding="utf-8")
    uri = ALLEX2.resolve().as_uri()
    variants = [text, text.replace("CSV mode over PDOs", "CSV mode over PDOs (edited)", 1)]
    burst, total = 50, 1000

    async def body(client: LanguageClient) -> None:
        await open_and_wait(client, ALLEX2, text)
        pid = client._server.pid  # type: ignore[union-attr]
        checks: list[lsp.PublishDiagnosticsParams] = client.published  # type: ignore[attr-defined]
        checks.clear()
        start = time.monotonic()
        before = 0
        for first in range(2, total + 2, burst):
            for version in range(first, first + burst):
                client.text_document_did_change(lsp.DidChangeTextDocumentParams(
                    lsp.VersionedTextDocumentIdentifier(uri=uri, version=version),
                    [lsp.TextDocumentContentChangeWholeDocument(variants[version % 2])],
                ))
            await published_for(client, lambda p, last=first + burst - 1: p.version == last)
            if not before:
                before = rss_kib(pid)
        after = rss_kib(pid)
        assert [p.diagnostics for p in checks if p.diagnostics] == []
        assert len(checks) < total - total // burst, len(checks)  # (published_for took the last of each burst)
        assert after - before < 30 * 1024, (before, after)
        assert time.monotonic() - start < 60

    run(body)


def test_hover_on_a_bus_and_a_node() -> None:
    text = ALLEX2.read_text(encoding="utf-8")
    report = check_json(ALLEX2)
    (bus,) = report["buses"]
    sent = [m["name"] for m in bus["messages"] if m["producer"] == "hip_l"]
    assert len(sent) == 3  # its two TPDOs (hip_l_state, hip_l_effort) and its heartbeat (heartbeat: 100 ms)

    async def body(client: LanguageClient) -> None:
        await open_and_wait(client, ALLEX2, text)
        row, col = line_of(text, "buses: [can0]")
        hover = await client.text_document_hover_async(lsp.HoverParams(doc(ALLEX2), lsp.Position(row, col + 10)))
        assert hover is not None
        assert f"utilisation: {bus['utilization']:.1%} worst case" in hover.contents.value  # type: ignore[union-attr]
        row, col = line_of(text, "producer: hip_l")
        hover = await client.text_document_hover_async(lsp.HoverParams(doc(ALLEX2), lsp.Position(row, col + 12)))
        assert hover is not None
        assert "sends 3 message(s)" in hover.contents.value  # type: ignore[union-attr]

    run(body)


def test_check_and_import_netcfg_never_load_the_language_server() -> None:
    """pygls is for `netcfg lsp` alone: a cold `netcfg check` does not pay for importing it."""
    code = (
        "import sys, netcfg, netcfg.commands\n"
        "sys.argv = ['netcfg', 'check', '-q', 'specs/allex2.yaml']\n"
        "assert netcfg.commands.main(sys.argv[1:]) == 0\n"
        "print(sorted(m for m in sys.modules if m.startswith(('pygls', 'lsprotocol', 'netcfg.lsp', "
        "'netcfg.commands.watch'))))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().endswith("[]"), proc.stdout


def test_an_unchanged_eds_is_read_once_across_edits(tmp_path: Path, needs_shared: None) -> None:
    """The server's checks run in one process, so the device profile netcfg.devices.eds caches per file version is
    built by the first check and reused by every edit after it; a new save of the EDS builds it again."""
    from netcfg.devices import eds as eds_module
    from netcfg.lsp.server import analyse_quietly

    shutil.copy(EPOS4_EDS, tmp_path / "drive.eds")
    text = ALLEX2.read_text(encoding="utf-8").replace("device: epos4", "device: {eds: drive.eds}", 1)
    path = tmp_path / "allex2.yaml"
    eds_module._profile.cache_clear()
    assert analyse_quietly(path, text).report["ok"]
    for n in range(3):
        assert analyse_quietly(path, text + f"# edit {n}\n").report["ok"]
    info = eds_module._profile.cache_info()
    assert (info.misses, info.hits) == (1, 3)
    time.sleep(0.01)
    (tmp_path / "drive.eds").write_bytes(EPOS4_EDS.read_bytes() + b"\n")
    assert analyse_quietly(path, text).report["ok"]
    assert eds_module._profile.cache_info().misses == 2
