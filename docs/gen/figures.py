"""Figures the pages quote in prose, each computed from what a command prints (its JSON), never typed by hand.

A page writes `<!--fig NAME-->VALUE<!--/fig-->`; `make docs-snippets` writes VALUE from the function registered
here under NAME, and tests/test_docs.py fails when a page's VALUE is no longer what the command gives.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from runnable import Workdir


@dataclass(frozen=True)
class Figure:
    commands: tuple[str, ...]  # netcfg command lines that print JSON (run in a working folder)
    value: Callable[..., str]  # the figure as the page writes it, from each command's JSON in turn


def _named(items: list[dict[str, Any]], name: str) -> dict[str, Any]:
    return next(item for item in items if item["name"] == name)


def _bus(report: dict[str, Any], name: str) -> dict[str, Any]:
    return _named(report["buses"], name)


def _msg(report: dict[str, Any], bus: str, name: str) -> dict[str, Any]:
    return _named(_bus(report, bus)["messages"], name)


def us(value: float) -> str:
    """A time in microseconds as the tables print it: thousands separated, one decimal when it has one."""
    text = f"{value:,.1f}"
    return text[:-2] if text.endswith(".0") else text


def pct(value: float) -> str:
    return f"{100 * value:.1f} %"


CHECK_ARM = "netcfg check specs/arm_canfd.yaml --format json"
SIM_ARM = "netcfg simulate specs/arm_canfd.yaml --stuffing exact --runs 4 --duration 10s --format json"


def _closest_joint(sim: dict[str, Any], check: dict[str, Any]) -> tuple[str, float, float]:
    """The joint state whose measured worst response comes closest to its bound: (name, measured, bound)."""
    bounds = {m["name"]: m["wcrt_us"] for b in check["buses"] for m in b["messages"]}
    joints = {m["name"]: m["response_us"]["max"] for m in sim["messages"] if m["name"].endswith("_state")}
    name = max(joints, key=lambda n: joints[n] / bounds[n])
    return name, joints[name], bounds[name]


FIGURES: dict[str, Figure] = {}


def figure(name: str, *commands: str) -> Callable[[Callable[..., str]], Callable[..., str]]:
    def register(fn: Callable[..., str]) -> Callable[..., str]:
        FIGURES[name] = Figure(commands, fn)
        return fn

    return register


def evaluate(names: set[str], workdir: Workdir) -> dict[str, str]:
    """The value of each named figure, each command run once."""
    from runnable import Example

    printed: dict[str, Any] = {}
    values = {}
    for name in sorted(names):
        if name not in FIGURES:
            raise KeyError(f"no figure named {name!r} in docs/gen/figures.py")
        fig = FIGURES[name]
        for command in fig.commands:
            if command not in printed:
                proc = workdir.run(Example("docs/gen/figures.py", 0, "shell", command), merge=False)
                printed[command] = json.loads(proc.stdout)
        values[name] = fig.value(*(printed[c] for c in fig.commands))
    return values


@figure("arm.load", CHECK_ARM)
def _arm_load(check: dict[str, Any]) -> str:
    return pct(_bus(check, "arm")["utilization"])


@figure("arm.bound.command", CHECK_ARM)
def _arm_command_bound(check: dict[str, Any]) -> str:
    return us(_msg(check, "arm", "arm_command")["wcrt_us"])


@figure("arm.bound.flow", CHECK_ARM)
def _arm_flow_bound(check: dict[str, Any]) -> str:
    flow = _named(check["flows"], "joint1_loop")
    return f"{us(flow['latency_min_us'])}-{us(flow['latency_max_us'])}"


@figure("arm.sim.command", SIM_ARM)
def _arm_command_measured(sim: dict[str, Any]) -> str:
    return us(round(_named(sim["messages"], "arm_command")["response_us"]["max"], 1))


@figure("arm.sim.closest", SIM_ARM, CHECK_ARM)
def _arm_closest(sim: dict[str, Any], check: dict[str, Any]) -> str:
    name, measured, bound = _closest_joint(sim, check)
    return f"{name}, {us(round(measured, 1))} us against {us(bound)} us"


@figure("arm.sim.flow", SIM_ARM)
def _arm_flow_measured(sim: dict[str, Any]) -> str:
    latency = _named(sim["flows"], "joint1_loop")["latency_us"]
    return f"{us(round(latency['min'], 1))}-{us(round(latency['max'], 1))}"


@figure("wrong_order.load", "netcfg check examples/wrong_order.yaml --format json")
def _wrong_order_load(check: dict[str, Any]) -> str:
    return pct(_bus(check, "body")["utilization"])


GAIT = "netcfg simulate specs/allex2.yaml --duration 8s --log gait.log > /dev/null && "
VERIFY_GAIT = GAIT + "netcfg verify specs/allex2.yaml gait.log --format json"
CHECK_ALLEX2 = "netcfg check specs/allex2.yaml --format json"


def _span(values: list[float], unit: Any = us) -> str:
    low, high = unit(min(values)), unit(max(values))
    return low if low == high else f"{low}-{high}"


def ms3(value_us: float) -> str:
    return f"{value_us / 1000:.3f}"


def _commands(items: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [item for item in items if item["name"].endswith("_cmd")]


@figure("allex2.verify.cmd_intervals", VERIFY_GAIT)
def _cmd_intervals(verify: dict[str, Any]) -> str:
    cmds = _commands(verify["messages"])
    return f"{ms3(min(m['period_us']['min'] for m in cmds))}-{ms3(max(m['period_us']['max'] for m in cmds))}"


@figure("allex2.verify.cmd_band", VERIFY_GAIT)
def _cmd_band(verify: dict[str, Any]) -> str:
    return _span([m["analysed_jitter_us"] for m in _commands(verify["messages"])])


@figure("allex2.verify.sync_period", VERIFY_GAIT)
def _sync_period(verify: dict[str, Any]) -> str:
    period = _named(verify["messages"], "can0_SYNC")["period_us"]
    return f"{ms3(period['min'])}-{ms3(period['max'])}"


@figure("allex2.check.cmd_wcrt", CHECK_ALLEX2)
def _cmd_wcrt(check: dict[str, Any]) -> str:
    return _span([m["wcrt_us"] for m in _commands(_bus(check, "can0")["messages"])])


# The seeds simulated (docs/explanation/evidence.md): 10 s per run, seeds 0-19, beside the analysis.
CHECK_CAMBADA = "netcfg check specs/cambada.yaml --format json"
SIM_CAMBADA = "netcfg simulate specs/cambada.yaml --duration 10s --runs 20 --format json"
SIM_CAMBADA_UNSYNC = "netcfg simulate specs/cambada.yaml --duration 10s --mode unsync --runs 20 --format json"
SYNC_FIRST = "sed 's/^      lsw: .*/&\\n      windows: sync-first/' specs/cambada.yaml > cambada_sync_first.yaml && "
CHECK_SYNC_FIRST = SYNC_FIRST + "netcfg check cambada_sync_first.yaml --format json"
SIM_SYNC_FIRST = SYNC_FIRST + "netcfg simulate cambada_sync_first.yaml --duration 10s --runs 20 --format json"
SIM_ALLEX2_GAIT = "netcfg simulate specs/allex2.yaml --duration 8s --format json"
SIM_ALLEX2 = "netcfg simulate specs/allex2.yaml --duration 10s --runs 20 --format json"
SIM_ALLEX2_SDO = "netcfg simulate specs/allex2.yaml --canopen sdo --duration 8s --format json"


def ms(value_us: float, digits: int = 2) -> str:
    return f"{value_us / 1000:.{digits}f}"


def _range(low: float, high: float, digits: int = 2) -> str:
    return ms(low, digits) if ms(low, digits) == ms(high, digits) else f"{ms(low, digits)}-{ms(high, digits)}"


def _sim_delivery(sim: dict[str, Any], flow: str) -> str:
    delivery = _named(sim["flows"], flow)["delivery_us"]
    return _range(delivery["min"], delivery["max"])


def _sync_delivery(check: dict[str, Any], flow: str) -> str:
    bound = _named(check["flows"], flow)["synchronised"]
    return _range(bound["delivery_min_us"], bound["delivery_max_us"])


for _flow in ("motion", "odometry"):
    figure(f"seeds.cambada.{_flow}.sim", SIM_CAMBADA)(lambda sim, f=_flow: _sim_delivery(sim, f))
    figure(f"seeds.cambada.{_flow}.bound", CHECK_CAMBADA)(lambda check, f=_flow: _sync_delivery(check, f))
    figure(f"seeds.sync_first.{_flow}.sim", SIM_SYNC_FIRST)(lambda sim, f=_flow: _sim_delivery(sim, f))
    figure(f"seeds.sync_first.{_flow}.bound", CHECK_SYNC_FIRST)(lambda check, f=_flow: _sync_delivery(check, f))


@figure("seeds.unsync.motion.sim", SIM_CAMBADA_UNSYNC)
def _unsync_motion_sim(sim: dict[str, Any]) -> str:
    flow = _named(sim["flows"], "motion")
    use, delivery = flow["latency_us"], flow["delivery_us"]
    return f"{_range(use['min'], use['max'], 1)} / {_range(delivery['min'], delivery['max'], 1)}"


@figure("seeds.unsync.motion.bound", CHECK_CAMBADA)
def _unsync_motion_bound(check: dict[str, Any]) -> str:
    bound = _named(check["flows"], "motion")["unsynchronised"]
    return (
        f"{_range(bound['latency_min_us'], bound['latency_max_us'], 1)} / "
        f"{_range(bound['delivery_min_us'], bound['delivery_max_us'], 1)}"
    )


@figure("seeds.unsync.odometry.sim", SIM_CAMBADA_UNSYNC)
def _unsync_odometry_sim(sim: dict[str, Any]) -> str:
    use = _named(sim["flows"], "odometry")["latency_us"]
    return _range(use["min"], use["max"], 1)


@figure("seeds.unsync.odometry.bound", CHECK_CAMBADA)
def _unsync_odometry_bound(check: dict[str, Any]) -> str:
    bound = _named(check["flows"], "odometry")["unsynchronised"]
    return _range(bound["latency_min_us"], bound["latency_max_us"], 1)


def _canopen(sim: dict[str, Any]) -> dict[str, Any]:
    result: dict[str, Any] = sim["protocols"]["can0"][0]
    return result


@figure("seeds.allex2.gait.sim", SIM_ALLEX2_GAIT)
def _gait_sim(sim: dict[str, Any]) -> str:
    cycle = _canopen(sim)
    samples = min(d["samples"] for d in cycle["drives"].values())
    return f"{samples} samples per joint, the TxPDOs done {ms(cycle['sync_completion_us']['max'])} ms after SYNC"


@figure("seeds.allex2.gait.bound", CHECK_ALLEX2)
def _gait_bound(check: dict[str, Any]) -> str:
    return f"{ms(_bus(check, 'can0')['sync']['worst_completion_us'])} ms worst"


def _latencies(flows: list[dict[str, Any]], key: str) -> str:
    return " / ".join(
        _range(_named(flows, f)[key]["min"], _named(flows, f)[key]["max"]) for f in ("joint_command", "joint_feedback")
    )


@figure("seeds.allex2.flows.sim", SIM_ALLEX2)
def _allex2_flows_sim(sim: dict[str, Any]) -> str:
    return _latencies(sim["flows"], "latency_us")


@figure("seeds.allex2.flows.bound", CHECK_ALLEX2)
def _allex2_flows_bound(check: dict[str, Any]) -> str:
    bounds = [_named(check["flows"], f)["synchronised"] for f in ("joint_command", "joint_feedback")]
    return " / ".join(_range(b["latency_min_us"], b["latency_max_us"]) for b in bounds)


@figure("seeds.allex2.sdo.sim", SIM_ALLEX2_SDO)
def _allex2_sdo(sim: dict[str, Any]) -> str:
    drives = _canopen(sim)["drives"].values()
    samples = [d["samples"] for d in drives]
    low = min(d["period_us"]["min"] for d in drives)
    high = max(d["period_us"]["max"] for d in drives)
    return f"{min(samples)}-{max(samples)} samples per joint, period {_range(low, high, 0)} ms"


def _flow_bound(check: dict[str, Any], flow: str, mode: str) -> str:
    bound = _named(check["flows"], flow)[mode]
    return _range(bound["latency_min_us"], bound["latency_max_us"], 3 if mode == "synchronised" else 1)


figure("allex2.feedback.sync", CHECK_ALLEX2)(lambda check: _flow_bound(check, "joint_feedback", "synchronised"))
figure("allex2.command.sync", CHECK_ALLEX2)(lambda check: _flow_bound(check, "joint_command", "synchronised"))
figure("allex2.feedback.unsync", CHECK_ALLEX2)(lambda check: _flow_bound(check, "joint_feedback", "unsynchronised"))
figure("allex2.command.unsync", CHECK_ALLEX2)(lambda check: _flow_bound(check, "joint_command", "unsynchronised"))


ALLEX2_ERRORS = (
    "sed 's/^      master_jitter: .*/&\\n    errors: {burst: 1, interval: 10ms, ber: 1e-5}/' specs/allex2.yaml"
    " > allex2_errors.yaml && netcfg check allex2_errors.yaml --format json"
)


def _per_hour(check: dict[str, Any], bus: str) -> str:
    return f"{_bus(check, bus)['errors']['errors_per_hour']:g}"


figure("allex2.errors_per_hour", CHECK_ALLEX2)(
    lambda check: f"{round(_bus(check, 'can0')['errors']['errors_per_hour'])}"
)
figure("cambada.errors_per_hour", CHECK_CAMBADA)(
    lambda check: f"{round(_bus(check, 'lowlevel')['errors']['errors_per_hour'])}"
)
figure("allex2.errors.per_hour", ALLEX2_ERRORS)(lambda check: _per_hour(check, "can0"))
figure("allex2.errors.exceed", ALLEX2_ERRORS)(
    lambda check: f"{_bus(check, 'can0')['errors']['exceed_probability_per_hour']:.3g}"
)


@figure("allex2.errors.sync_delay", ALLEX2_ERRORS, CHECK_ALLEX2)
def _sync_delay(with_errors: dict[str, Any], without: dict[str, Any]) -> str:
    def completion(check: dict[str, Any]) -> float:
        return float(_bus(check, "can0")["sync"]["worst_completion_us"])

    return us(completion(with_errors) - completion(without))
