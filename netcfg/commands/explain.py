"""`netcfg check SPEC --explain MESSAGE|FLOW`, check's mode that derives one bound: a CAN message's worst-case
response time and the one change that would make it meet its deadline (netcfg.explain), or a flow's latency beside
its steps' figures (netcfg.explain_flow).

Exit codes: 0 the message or flow meets its deadline, 1 it misses or the spec has errors, 2 no such CAN message or
flow, or an unreadable file.
"""

from __future__ import annotations

import sys
from pathlib import Path

from netcfg import jsontext
from netcfg.check import load_model
from netcfg.diagnostics import Collector, sort_diagnostics
from netcfg.importers import ImportOptions


def explain_command(paths: list[Path], name: str, fmt: str, options: ImportOptions) -> int:
    if len(paths) != 1:
        print("netcfg: --explain takes one spec", file=sys.stderr)
        return 2
    diags = Collector()
    try:
        m = load_model(paths[0], diags, options)
    except OSError as exc:
        print(f"netcfg: cannot read {paths[0]}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    if m is None or diags.errors:
        for d in sort_diagnostics(diags.items):
            print(d, file=sys.stderr)
        return 1
    if name in m.flows:  # a flow: its bounds beside its steps' own figures, from the model already loaded
        from netcfg.analyze import analyze
        from netcfg.explain_flow import explain_flow
        from netcfg.explain_flow import text as flow_text

        flow_doc = explain_flow(m, analyze(m, Collector()), name)
        print(jsontext.dumps(flow_doc, indent=2) if fmt == "json" else flow_text(flow_doc))
        return 1 if flow_doc["meets"] is False else 0
    from netcfg.explain import NotExplained, explain, text

    try:
        doc = explain(m, name)
    except NotExplained as exc:
        print(f"netcfg: {exc}", file=sys.stderr)
        return 2
    print(jsontext.dumps(doc, indent=2) if fmt == "json" else text(doc))
    return 1 if doc["meets"] is False else 0
