"""Spec -> Model: fill in defaults (identifiers, periods, FTT ids, device objects) and check everything that
needs more than one item to decide: references, identifiers, PDO maps against device dictionaries, EC
multiples, offsets. Like a linter, it reports every problem it finds, not just the first.

The core (`core`) resolves what every spec has: names, nodes, tasks, a message's common fields, identifiers;
`flows` the end-to-end chains. Each protocol's own rules are its layer's (netcfg.protocols: `Protocol.rules`), over
its link's (netcfg.links).
"""

from __future__ import annotations

from pathlib import Path as FsPath

from netcfg import model, protocols
from netcfg.diagnostics import Collector
from netcfg.protocols.canopen.pdo import snake
from netcfg.resolve.actuators import add_reply_senders, resolve_actuators
from netcfg.resolve.core import Resolver
from netcfg.resolve.flows import resolve_flows
from netcfg.resolve.joints import resolve_joints
from netcfg.resolve.nodes import resolve_nodes
from netcfg.rules import BusRules
from netcfg.spec import schema
from netcfg.spec.source import SourceMap
from netcfg.timing.offsets import derive_offsets

__all__ = ["RULES", "resolve", "snake"]

# The resolver's hooks for each protocol of the spec language (schema.Bus.protocol), as its layer gives them.
RULES: dict[str, type[BusRules]] = {name: p.rules() for name, p in protocols.PROTOCOLS.items()}


def resolve(spec: schema.Spec, smap: SourceMap, diags: Collector, spec_dir: FsPath) -> model.Model | None:
    """Build the Model; returns None (with errors in diags) when the spec is inconsistent."""
    r = Resolver(spec, smap, diags, spec_dir, RULES)
    r.check_unique_names()
    r.resolve_buses()
    resolve_nodes(r)
    r.resolve_messages()
    resolve_actuators(r)  # an actuator profile's messages and reply tasks, as if the spec had written them
    for rules in r.protocols.values():
        rules.resolve_items()  # implicit messages, triggers, topologies
    r.check_tasks_activated()
    r.check_identifiers()
    resolve_flows(r)
    resolve_joints(r)
    if not diags.errors:
        add_reply_senders(r)
    if not diags.errors:
        derive_offsets(r.model, r.err)
    if diags.errors:
        return None
    return r.model
