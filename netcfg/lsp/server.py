"""`netcfg lsp`: the language server, on pygls (a maintained LSP framework: JSON-RPC framing, the protocol's types
and incremental text sync are its, not ours).

Each open spec is checked by the same pipeline as `netcfg check` (netcfg.check.analyse_loaded) on the editor's text,
in one worker thread, so the server keeps answering while a check runs. An edit that arrives during a check only
replaces the text waiting for the next one: when the running check ends, the newest text is checked and the
versions in between are never checked (no fixed delay: a check starts as soon as the worker is free).
The process lives as long as the editor, so what netcfg caches per file version (EDS object dictionaries and
device profiles, netcfg.devices.eds) is read once and reused by every check after it.
"""

from __future__ import annotations

import asyncio
import gc
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lsprotocol import types as lsp
from pygls.lsp.server import LanguageServer
from pygls.uris import from_fs_path, to_fs_path

from netcfg import __version__
from netcfg.gc_pause import gc_paused
from netcfg.inputs import SPEC_SUFFIXES
from netcfg.lsp import document as doc

SEVERITY = {"error": lsp.DiagnosticSeverity.Error, "warning": lsp.DiagnosticSeverity.Warning}


@dataclass
class Checked:
    """The last check of one spec: its report, the names it defines, the text it was made of."""

    version: int | None
    lines: list[str]
    report: dict[str, Any]
    index: doc.Index
    files: list[Path]  # the files it names (EDS, DBC)
    published: set[str] = field(default_factory=set)  # the URIs this spec's diagnostics went to


@dataclass
class Result:
    """What the worker hands back: diagnostics by URI (LSP ranges), the report, the index (None: keep the last)."""

    report: dict[str, Any]
    index: doc.Index | None
    diagnostics: dict[str, list[lsp.Diagnostic]]
    files: list[Path]


def analyse(path: Path, text: str) -> Result:
    """Check one spec's text as `netcfg check` does; diagnostics at the same codes, lines and columns (0-based
    here), grouped by the file they are in (an EDS's or a DBC's own lines go to that file)."""
    from netcfg.check import analyse_loaded, named_files

    loaded, report = analyse_loaded(path, None, text)
    lines = text.splitlines()
    by_uri: dict[str, list[lsp.Diagnostic]] = {}
    own = str(path)
    others: dict[str, list[str]] = {}
    for severity in ("errors", "warnings"):
        for d in report[severity]:
            if d["file"] == own:
                uri, file_lines = _uri(path), lines
            else:
                other = Path(d["file"])
                uri = _uri(other if other.is_absolute() else Path.cwd() / other)
                file_lines = others.setdefault(uri, _read_lines(other))
            by_uri.setdefault(uri, []).append(_diagnostic(d, severity[:-1], file_lines))
    index = None
    if loaded.smap is not None and isinstance(loaded.data, dict):
        index = doc.build_index(loaded.data, loaded.smap)
    return Result(report, index, by_uri, [f.resolve() for f in named_files(path, loaded.data)])


def analyse_quietly(path: Path, text: str) -> Result:
    """analyse without the cyclic collector: a check makes ~10^5 objects that all live until it ends, and each
    collection during it only walks them (about a third of a warm 1,000-message check). The server collects once
    it is idle instead (collect_idle)."""
    with gc_paused():
        return analyse(path, text)


_frozen = False


def collect_idle() -> None:
    """Free the last checks' cycles; the first time, move what every check shares (imported modules, schema models,
    cached device profiles) out of the collector's sight, so that later collections walk only what checks made."""
    global _frozen
    gc.collect()
    if not _frozen:
        gc.freeze()
        _frozen = True


def _uri(path: Path) -> str:
    return from_fs_path(str(path)) or path.as_uri()


def _read_lines(path: Path) -> list[str]:
    try:
        return path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return []


def _diagnostic(d: dict[str, Any], severity: str, lines: list[str]) -> lsp.Diagnostic:
    word = doc.diagnostic_word(lines, d["line"] - 1, d["column"] - 1, d["message"])
    text = lines[word.line] if 0 <= word.line < len(lines) else ""
    end = word.end if word.end > word.start else word.start + 1
    return lsp.Diagnostic(
        range=lsp.Range(
            lsp.Position(word.line, doc.utf16_column(text, word.start)),
            lsp.Position(word.line, doc.utf16_column(text, end)),
        ),
        message=d["message"],
        severity=SEVERITY[severity],
        code=d["code"],
        source="netcfg",
    )


class NetcfgServer(LanguageServer):
    def __init__(self) -> None:
        super().__init__("netcfg", __version__, text_document_sync_kind=lsp.TextDocumentSyncKind.Incremental)
        self.checked: dict[str, Checked] = {}
        self.waiting: dict[str, tuple[int | None, str]] = {}  # the newest text not checked yet, by URI
        self.checker: asyncio.Task[None] | None = None
        self.running: str | None = None  # the URI being checked
        self.worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="netcfg-check")
        self.published: dict[str, dict[str, list[lsp.Diagnostic]]] = {}  # target URI -> spec URI -> diagnostics

    def schedule(self, uri: str, version: int | None, text: str) -> None:
        """Check this text once the worker is free; replaces any text of the same spec still waiting."""
        self.waiting[uri] = (version, text)
        if self.checker is None or self.checker.done():
            self.checker = asyncio.get_running_loop().create_task(self._run())

    async def _run(self) -> None:
        loop = asyncio.get_running_loop()
        while self.waiting:
            while self.waiting:
                uri = next(iter(self.waiting))
                version, text = self.waiting.pop(uri)
                path = Path(to_fs_path(uri) or uri)
                self.running = uri
                try:
                    result = await loop.run_in_executor(self.worker, analyse_quietly, path, text)
                except Exception as exc:  # a bug in netcfg: say so in the editor, keep serving
                    self.window_log_message(lsp.LogMessageParams(
                        lsp.MessageType.Error, f"netcfg: internal error checking {path}: {exc!r}"
                    ))
                    continue
                finally:
                    self.running = None
                self._publish(uri, version, text, result)
            # idle: the cycles the checks left (models, reports) are freed now, not during the next check; an edit
            # that comes meanwhile is checked right after (the outer loop)
            await loop.run_in_executor(self.worker, collect_idle)

    def _publish(self, uri: str, version: int | None, text: str, result: Result) -> None:
        last = self.checked.get(uri)
        index = result.index or (last.index if last else doc.Index())
        targets = set(result.diagnostics) | {uri} | (last.published if last else set())
        self.checked[uri] = Checked(
            version, text.splitlines(), result.report, index, result.files, set(result.diagnostics)
        )
        for target in targets:
            mine = result.diagnostics.get(target, [])
            self.published.setdefault(target, {})[uri] = mine
            merged = [d for source in self.published[target].values() for d in source]
            self.text_document_publish_diagnostics(
                lsp.PublishDiagnosticsParams(target, merged, version if target == uri else None)
            )

    async def settled(self, uri: str) -> Checked | None:
        """The spec's last check, after the check of any text of it still waiting or running."""
        while self.checker is not None and not self.checker.done() and (uri in self.waiting or self.running == uri):
            await asyncio.shield(self.checker)
        return self.checked.get(uri)


def is_spec(uri: str) -> bool:
    return uri.lower().endswith(SPEC_SUFFIXES)


def make_server() -> NetcfgServer:
    server = NetcfgServer()

    @server.feature(lsp.TEXT_DOCUMENT_DID_OPEN)
    def did_open(ls: NetcfgServer, params: lsp.DidOpenTextDocumentParams) -> None:
        if is_spec(params.text_document.uri):
            ls.schedule(params.text_document.uri, params.text_document.version, params.text_document.text)

    @server.feature(lsp.TEXT_DOCUMENT_DID_CHANGE)
    def did_change(ls: NetcfgServer, params: lsp.DidChangeTextDocumentParams) -> None:
        uri = params.text_document.uri
        if is_spec(uri):
            ls.schedule(uri, params.text_document.version, ls.workspace.get_text_document(uri).source)

    @server.feature(lsp.TEXT_DOCUMENT_DID_SAVE)
    def did_save(ls: NetcfgServer, params: lsp.DidSaveTextDocumentParams) -> None:
        # a saved EDS or DBC: check again the open specs whose last check read it (the caches see its new mtime)
        saved = params.text_document.uri
        for uri, checked in list(ls.checked.items()):
            if uri != saved and (saved in checked.published or _path(saved) in checked.files):
                text = ls.workspace.get_text_document(uri).source
                ls.schedule(uri, checked.version, text)

    @server.feature(lsp.TEXT_DOCUMENT_DID_CLOSE)
    def did_close(ls: NetcfgServer, params: lsp.DidCloseTextDocumentParams) -> None:
        uri = params.text_document.uri
        checked = ls.checked.pop(uri, None)
        ls.waiting.pop(uri, None)
        for target in checked.published | {uri} if checked else ():
            ls.published.get(target, {}).pop(uri, None)
            merged = [d for source in ls.published.get(target, {}).values() for d in source]
            ls.text_document_publish_diagnostics(lsp.PublishDiagnosticsParams(target, merged))

    @server.feature(lsp.TEXT_DOCUMENT_HOVER)
    async def hover(ls: NetcfgServer, params: lsp.HoverParams) -> lsp.Hover | None:
        found = await _target(ls, params.text_document.uri, params.position)
        if found is None:
            return None
        checked, cursor, (kind, name) = found
        text = doc.hover_text(kind, name, checked.report)
        if text is None:
            return None
        return lsp.Hover(lsp.MarkupContent(lsp.MarkupKind.Markdown, text), _range(checked.lines, cursor.word))

    @server.feature(lsp.TEXT_DOCUMENT_DEFINITION)
    async def definition(ls: NetcfgServer, params: lsp.DefinitionParams) -> lsp.Location | None:
        uri = params.text_document.uri
        checked = await ls.settled(uri)
        if checked is None:
            return None
        lines = _lines(ls, uri)
        cursor = _cursor(lines, params.position)
        if doc.expected_kind(cursor) == "file" and cursor.word.text:
            base = Path(to_fs_path(uri) or uri).parent
            file = (base / cursor.word.text).resolve()
            if file.is_file():
                return lsp.Location(_uri(file), lsp.Range(lsp.Position(0, 0), lsp.Position(0, 0)))
            return None
        target = doc.target_of(cursor, checked.index)
        if target is None:
            return None
        line, col = checked.index.find(*target) or (0, 0)
        word = doc.Word(line, col, col + len(target[1]), target[1])
        return lsp.Location(uri, _range(lines, word))

    @server.feature(
        lsp.TEXT_DOCUMENT_COMPLETION, lsp.CompletionOptions(trigger_characters=[" ", "[", ",", "{"])
    )
    def completion(ls: NetcfgServer, params: lsp.CompletionParams) -> lsp.CompletionList:
        uri = params.text_document.uri
        lines = _lines(ls, uri)
        cursor = _cursor(lines, params.position)
        items: list[lsp.CompletionItem] = []
        kind = doc.expected_kind(cursor)
        checked = ls.checked.get(uri)
        if cursor.key is None:
            for key, description in doc.keys_at(cursor.path).items():
                items.append(lsp.CompletionItem(
                    key, kind=lsp.CompletionItemKind.Property, detail=description or None, insert_text=f"{key}: "
                ))
        elif kind not in (None, "file") and cursor.key != "name" and checked is not None:
            for name in checked.index.of(kind):
                items.append(lsp.CompletionItem(name, kind=lsp.CompletionItemKind.Reference, detail=kind))
        else:
            for word in doc.literals_at(cursor.path):
                items.append(lsp.CompletionItem(word, kind=lsp.CompletionItemKind.EnumMember))
        return lsp.CompletionList(is_incomplete=False, items=items)

    @server.feature(lsp.TEXT_DOCUMENT_CODE_ACTION)
    def code_action(ls: NetcfgServer, params: lsp.CodeActionParams) -> list[lsp.CodeAction]:
        uri = params.text_document.uri
        actions: list[lsp.CodeAction] = []
        for d in params.context.diagnostics:
            meant = doc.suggested(d.message)
            if meant is None or d.range.start.line != d.range.end.line:
                continue
            edit = lsp.TextEdit(d.range, meant)
            actions.append(lsp.CodeAction(
                f"Replace with '{meant}'",
                kind=lsp.CodeActionKind.QuickFix,
                diagnostics=[d],
                is_preferred=True,
                edit=lsp.WorkspaceEdit(changes={uri: [edit]}),
            ))
        return actions

    return server


def _path(uri: str) -> Path:
    return Path(to_fs_path(uri) or uri).resolve()


def _lines(ls: NetcfgServer, uri: str) -> list[str]:
    return ls.workspace.get_text_document(uri).source.splitlines()


def _cursor(lines: list[str], position: lsp.Position) -> doc.Cursor:
    text = lines[position.line] if position.line < len(lines) else ""
    return doc.cursor_at(lines, position.line, doc.code_point_column(text, position.character))


def _range(lines: list[str], word: doc.Word) -> lsp.Range:
    text = lines[word.line] if 0 <= word.line < len(lines) else ""
    return lsp.Range(
        lsp.Position(word.line, doc.utf16_column(text, word.start)),
        lsp.Position(word.line, doc.utf16_column(text, word.end)),
    )


async def _target(
    ls: NetcfgServer, uri: str, position: lsp.Position
) -> tuple[Checked, doc.Cursor, tuple[str, str]] | None:
    checked = await ls.settled(uri)
    if checked is None:
        return None
    cursor = _cursor(_lines(ls, uri), position)
    target = doc.target_of(cursor, checked.index)
    return None if target is None else (checked, cursor, target)


def serve() -> int:
    """Serve one editor over stdin/stdout until it disconnects."""
    os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
    make_server().start_io()
    return 0
