"""Which items of a flow's step before it a reader takes its data from: one rule for the analysis
(netcfg.timing.flows) and for the simulator (netcfg.sim.flows), which measures what the analysis bounds. A leaf
module, so that the simulator reads it without the analysis or the model."""

from __future__ import annotations

from collections.abc import Callable, Collection
from typing import Protocol


class Step(Protocol):
    """A flow's step, in the model or in a runtime configuration."""

    @property
    def kind(self) -> str: ...
    @property
    def refs(self) -> tuple[str, ...]: ...


def step_inputs(
    prev: Step, kind: str, ref: str, consumers: Callable[[str], Collection[str]], producer: Callable[[str], str]
) -> tuple[str, ...]:
    """The items of the step before that a reader (`ref`, a `kind`) takes its data from: a task those its node
    receives or runs, a message those its producer runs; all of them when none is local."""
    if kind == "task":
        node = ref.split(".", 1)[0]
        mine = tuple(
            r for r in prev.refs
            if (prev.kind == "message" and node in consumers(r))
            or (prev.kind == "task" and r.split(".", 1)[0] == node)
        )
    else:
        sender = producer(ref)
        mine = tuple(r for r in prev.refs if prev.kind == "task" and r.split(".", 1)[0] == sender)
    return mine or prev.refs
