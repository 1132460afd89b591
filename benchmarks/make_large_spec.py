"""Write specs/large_plant.yaml: a large, synthetic but plausible netcfg spec for the benchmarks.

A production cell on three buses: `motion` (CANopen, 1 Mbit/s, SYNC every 10 ms) with 25 maxon EPOS4 axes
whose PDO maps follow specs/allex2.yaml (velocity axes every SYNC, position axes every 2nd); `plant` (plain CAN,
500 kbit/s) with a PLC, HMI, safety PLC, conveyors, I/O racks, temperature zones, presses, cameras and meters
using explicit, deadline-monotonic identifiers; `cell` (FTT-CAN, 1 Mbit/s, EC 5 ms) with a spindle loop whose
offsets netcfg derives (`offset: auto`), two robots, tools, fixtures and asynchronous traffic. Two gateways
link the buses and a few flows cross them. Deterministic (fixed seed, stable order): rerunning it rewrites the
same file.

    python benchmarks/make_large_spec.py            # writes specs/large_plant.yaml
"""

from __future__ import annotations

import json
import random
from pathlib import Path
from typing import Any

SEED = 4242
OUT = Path(__file__).resolve().parent.parent / "specs" / "large_plant.yaml"
Item = dict[str, Any]
MACRO_EC, LSW_US = 20, 3000


class Hex(int):
    """An integer written as 0x... in the YAML."""


def ms(x: float) -> str:
    return f"{x:g} ms"


def msg(name: str, producer: str, consumers: list[str], size: int | None, when: str, **extra: Any) -> Item:
    """when: '20' (period, ms), 's100' (sporadic, min. inter-arrival in ms), '-' (on-demand) or '' (in extra)."""
    out: Item = {"name": name, "producer": producer, "consumers": consumers}
    out.update({"size": size} if size is not None else {})
    if when == "-":
        out["type"] = "on-demand"
    elif when.startswith("s"):
        out["min_interarrival"] = ms(int(when[1:]))
    elif when:
        out["period"] = ms(int(when))
    return {**out, **extra}


def node(name: str, buses: list[str], *tasks: str, **extra: Any) -> Item:
    """tasks: 'name period/- wcet bcet' in us, e.g. 'read 10000 1200 300'; period '-' = triggered."""
    out: Item = {"name": name, **extra, "buses": buses}
    for t in tasks:
        tname, period, wcet, bcet = t.split()
        task: Item = {"name": tname}
        if period.startswith("@"):
            task["on_message"] = period[1:]
        elif period != "-":
            task["period"] = ms(int(period) / 1000)
        out.setdefault("tasks", []).append({**task, "wcet": f"{wcet} us", "bcet": f"{bcet} us"})
    return out


def canopen(rng: random.Random) -> tuple[list[Item], list[Item], list[str]]:
    """25 EPOS4 axes: 8 in CSV mode every SYNC (RPDO1 0x60FF+0x60B1, TPDO1 position+velocity, TPDO2 torque +
    current every 10th SYNC, RPDO2 interpolation period on demand), 17 in CSP mode every 2nd SYNC."""
    master = node("motion_master", ["motion", "plant"], "write 10000 1500 400", "read 10000 1200 300",
                  "relay 20000 300 100", role="master", node_id=127)  # fmt: skip
    nodes, msgs = [master], []
    axes = [f"axis{i:02d}" for i in range(1, 26)]
    fast = set(rng.sample(axes, 8))
    for i, axis in enumerate(axes, 1):
        nodes.append({"name": axis, "node_id": i, "device": "epos4", "heartbeat": ms(100), "buses": ["motion"]})
        mm, me = "motion_master", [axis]
        if axis in fast:
            msgs += [
                msg(f"{axis}_cmd", mm, me, None, "10", pdo={"rpdo": 1, "transmission": 255,
                                                            "map": [Hex(0x60FF), Hex(0x60B1)]}),
                msg(f"{axis}_interp", mm, me, None, "-", pdo={"rpdo": 2, "transmission": 255,
                                                              "map": ["0x60C2:1", "0x60C2:2"]}),
                msg(f"{axis}_state", axis, [mm], None, "", pdo={"tpdo": 1, "transmission": 1,
                                                                   "map": [Hex(0x6064), Hex(0x606C)]}),
                msg(f"{axis}_effort", axis, [mm], None, "", pdo={"tpdo": 2, "transmission": 10,
                                                                    "map": [Hex(0x6077), "0x30D1:2"]}),
            ]  # fmt: skip
        else:
            msgs += [
                msg(f"{axis}_cmd", mm, me, None, "20", pdo={"rpdo": 1, "transmission": 255, "map": [Hex(0x607A)]}),
                msg(f"{axis}_state", axis, [mm], None, "", pdo={"tpdo": 1, "transmission": 2,
                                                                   "map": [Hex(0x6064), Hex(0x6041)]}),
            ]  # fmt: skip
    return nodes, msgs, axes


# Field devices on the plant bus: count and 'suffix:when:bytes' per message; '<' = sent by the line PLC to it.
FIELD = {
    "conveyor": (7, "<speed_ref:50:4 <mode:100:1 speed:50:4 encoder:50:4 status:100:2 current:100:4 tension:500:2 "
                 "motor_temp:1000:2 runtime:1000:4 diag:1000:8 fault:s100:2"),
    "io_rack": (6, "<outputs:50:8 <config:-:8 inputs_a:50:8 inputs_b:100:8 analog_1:100:8 analog_2:200:8 "
                "counters:200:8 analog_3:500:8 status:500:2 temperature:1000:4 diag:1000:8"),
    "temp_zone": (4, "<setpoint:500:4 <heater_cmd:200:2 temps_a:200:8 temps_b:500:8 heater_state:200:2 "
                  "diag:1000:4 alarm:s500:1"),
    "press": (2, "<cmd:50:4 <profile:-:8 force:10:4 position:10:4 status:50:2 die_temp:500:4 tonnage_peak:s500:4 "
              "cycle_count:1000:4 diag:1000:8 fault:s50:2"),
    "vision": (2, "<trigger:100:1 result:100:8 quality:200:8 status:500:2 diag:1000:8"),
    "meter": (2, "power:200:8 voltages:500:6 currents:500:6 energy:1000:8 harmonics:1000:8 status:1000:2"),
}  # fmt: skip
# The PLC, HMI, safety PLC and gateway traffic: 'name producer consumer+consumer when bytes'.
PLANT = """
estop safety_plc line_plc+cell_gateway+motion_master s10 1
safety_state safety_plc line_plc+hmi 20 2
guard_doors safety_plc line_plc+hmi 50 2
light_curtains safety_plc line_plc 20 2
safety_diag safety_plc hmi 1000 8
plc_alive line_plc hmi+safety_plc 100 1
line_state line_plc hmi+cell_gateway+motion_master 100 4
time_sync line_plc hmi+cell_gateway 1000 8
operator_cmd hmi line_plc s50 4
recipe hmi line_plc - 8
hmi_alive hmi line_plc 500 1
motion_state motion_master line_plc+hmi 50 4
axis_faults motion_master line_plc+hmi s100 8
cell_state cell_gateway line_plc+hmi 50 8
tool_status cell_gateway line_plc 100 8
cell_alarm cell_gateway line_plc+hmi s100 2
cell_job line_plc cell_gateway 200 8
"""


def plant(rng: random.Random, axes: list[str]) -> tuple[list[Item], list[Item]]:
    nodes = [
        node("line_plc", ["plant"], "speed_loop 50000 2000 1000", "sequencer 50000 5000 2000"),
        node("hmi", ["plant"], "display 100000 20000 5000"),
        node("safety_plc", ["plant"], "monitor 5000 500 200"),
    ]
    msgs = []
    for line in PLANT.split("\n")[1:-1]:
        name, producer, consumers, when, size = line.split()
        msgs.append(msg(name, producer, consumers.split("+"), int(size), when))
    for g in range(5):
        group = ", ".join(axes[5 * g : 5 * g + 5])
        msgs.append(msg(f"axes_g{g + 1}_position", "motion_master", ["line_plc", "hmi"], 8, "20",
                        description=f"positions of {group}, 16 bits each"))  # fmt: skip
    for kind, (count, table) in FIELD.items():
        for k in range(1, count + 1):
            name = f"{kind}{k:02d}"
            tasks = ["ctrl 10000 400 150"] if kind == "conveyor" else []
            nodes.append(node(name, ["plant"], *tasks))
            for entry in table.split():
                suffix, when, size = entry.lstrip("<").split(":")
                if entry.startswith("<"):
                    msgs.append(msg(f"{name}_{suffix}", "line_plc", [name], int(size), when))
                else:
                    readers = ["line_plc"] + (["hmi"] if rng.random() < 0.4 else [])
                    msgs.append(msg(f"{name}_{suffix}", name, readers, int(size), when))

    def urgency(m: Item) -> tuple[float, str]:  # deadline-monotonic ids, on-demand last, gaps of 4
        t = m.get("period") or m.get("min_interarrival")
        return (float(t.split()[0]) if t else 1e9, m["name"])

    ids = {m["name"]: Hex(0x010 + 4 * rank) for rank, m in enumerate(sorted(msgs, key=urgency))}
    return nodes, [{"name": m["name"], "id": ids[m["name"]], **m} for m in msgs]


# Synchronous messages on the FTT-CAN bus: 'name producer consumer+consumer bytes period_EC offset_EC|auto|-'.
# '-' lets the generator pick the offset that keeps the busiest EC's synchronous window shortest.
SYNC = """
spindle_position spindle_enc motion_ctrl 4 2 auto
spindle_cmd motion_ctrl spindle_drive 4 2 auto
spindle_state spindle_drive motion_ctrl+cell_gateway 8 4 -
spindle_temp spindle_drive cell_gateway 4 20 -
traj_status motion_ctrl cell_gateway 8 4 -
scanner_zone scanner motion_ctrl+robot01+robot02 2 1 -
scanner_status scanner cell_gateway 2 20 -
cell_cmd cell_gateway motion_ctrl 8 20 -
""" + "".join(
    f"{r}_joints_cmd_{j} motion_ctrl {r} 8 4 0\n{r}_joints_state_{j} {r} motion_ctrl 8 4 -\n"
    for r in ("robot01", "robot02") for j in (1, 2, 3)
) + "".join(f"{r}_io {r} cell_gateway 4 10 -\n{r}_status {r} cell_gateway 2 20 -\n" for r in ("robot01", "robot02")) + (
    "".join(f"{t}_state {t} motion_ctrl 6 4 -\n{t}_cmd motion_ctrl {t} 4 4 -\n{t}_force {t} motion_ctrl 8 2 -\n"
            for t in ("tool01", "tool02", "tool03", "tool04"))
) + "".join(
    f"{f}_clamp_state {f} motion_ctrl 2 10 -\n{f}_clamp_cmd motion_ctrl {f} 1 10 -\n"
    f"{f}_pressure {f} cell_gateway 4 4 -\n"
    for f in ("fixture01", "fixture02")
) + "".join(f"cell_setpoints_{k} cell_gateway motion_ctrl 8 10 -\n" for k in (1, 2, 3, 4))  # fmt: skip
TRIGGERS = [  # name, FTT id, period, offset, tasks
    ("enc_sample", 0, "2 EC", "auto", ["spindle_enc.sample"]),
    ("ctrl_compute", 1, "2 EC", "auto", ["motion_ctrl.compute"]),
    ("drive_apply", 2, "2 EC", "auto", ["spindle_drive.apply"]),
    ("robot_plan", 3, "4 EC", "0 EC", ["motion_ctrl.plan"]),
    ("robot_interp", 4, "4 EC", "1 EC", ["robot01.interp", "robot02.interp"]),
    ("tool_poll", 5, "10 EC", "5 EC", [f"tool{t:02d}.poll" for t in range(1, 5)]),
]
AUTO_OFFSETS = {"spindle_position": 1, "spindle_cmd": 3}  # what netcfg derives from the spindle_loop flow
STATIONS = ["motion_ctrl", "spindle_enc", "spindle_drive", "robot01", "robot02", "tool01", "tool02", "tool03",
            "tool04", "fixture01", "fixture02", "scanner"]  # fmt: skip


def ftt(rng: random.Random) -> tuple[list[Item], list[Item], list[Item]]:
    nodes = [
        node("ftt_master", ["cell"], role="master"),
        node("cell_gateway", ["cell", "plant"], "relay @estop 100 50"),
        node("motion_ctrl", ["cell"], "compute - 1500 900", "plan - 2000 1000"),
        node("spindle_enc", ["cell"], "sample - 200 100"),
        node("spindle_drive", ["cell"], "apply - 100 50"),
        *(node(f"robot{r:02d}", ["cell"], "interp - 800 500", "halt @estop_relay 50 50") for r in (1, 2)),
        *(node(f"tool{t:02d}", ["cell"], "poll - 300 100") for t in range(1, 5)),
        *(node(f"fixture{f:02d}", ["cell"]) for f in (1, 2)),
        node("scanner", ["cell"]),
    ]
    triggers = [
        {"name": n, "bus": "cell", "ftt_id": i, "period": p, "offset": o, "tasks": t} for n, i, p, o, t in TRIGGERS
    ]
    rows = [line.split() for line in SYNC.strip().split("\n")]
    load = [0] * MACRO_EC  # synchronous window per EC, worst-case bits = us at 1 Mbit/s
    offsets: dict[str, int] = {}
    for name, _, _, size, period, off in sorted(rows, key=lambda r: (int(r[4]), -int(r[3]), r[0])):
        p, bits = int(period), 55 + 10 * int(size)
        o = AUTO_OFFSETS[name] if off == "auto" else int(off) if off != "-" else None
        if o is None:
            o = min(range(p), key=lambda x: (max(load[k] for k in range(x, MACRO_EC, p)), x))
        for k in range(o, MACRO_EC, p):
            load[k] += bits
        offsets[name] = o
    assert max(load) <= LSW_US, f"the busiest EC needs {max(load)} us"
    msgs = [
        msg(name, producer, consumers.split("+"), int(size), "", period=f"{period} EC",
            offset="auto" if off == "auto" else f"{offsets[name]} EC")
        for name, producer, consumers, size, period, off in rows
    ]  # fmt: skip
    asyn = [msg("estop_relay", "cell_gateway", ["robot01", "robot02"], 1, "s10")]
    for st in STATIONS:
        asyn += [
            msg(f"{st}_alarm", st, ["cell_gateway"], rng.choice((2, 4)), f"s{rng.choice((50, 100, 200))}"),
            msg(f"{st}_diag", st, ["cell_gateway"], 8, str(rng.choice((500, 1000))), window="async"),
            msg(f"{st}_param_req", "cell_gateway", [st], 8, "s200"),
            msg(f"{st}_param_resp", st, ["cell_gateway"], 8, "s200"),
            msg(f"{st}_config", "cell_gateway", [st], 8, "-"),
        ]
    msgs += [{"name": m["name"], "id": Hex(0x300 + 2 * rank), **m} for rank, m in enumerate(asyn)]
    return nodes, msgs, triggers


FLOWS = [
    {"name": "spindle_loop", "deadline": ms(30), "description": "encoder to spindle drive, time-triggered",
     "chain": ["spindle_enc.sample", "spindle_position", "motion_ctrl.compute", "spindle_cmd", "spindle_drive.apply"]},
    {"name": "robot_motion", "deadline": ms(40),
     "chain": ["motion_ctrl.plan", [f"robot01_joints_cmd_{j}" for j in (1, 2, 3)], "robot01.interp"]},
    {"name": "estop_path", "deadline": ms(20), "description": "safety PLC to the robots across the gateway",
     "chain": ["safety_plc.monitor", "estop", "cell_gateway.relay", "estop_relay", ["robot01.halt", "robot02.halt"]]},
    {"name": "axis_feedback", "deadline": ms(250), "description": "axis positions to the HMI across the gateway",
     "chain": [[f"axis0{i}_state" for i in range(1, 6)], "motion_master.read", "axes_g1_position", "hmi.display"]},
    {"name": "conveyor_speed", "deadline": ms(60),
     "chain": ["line_plc.speed_loop", "conveyor01_speed_ref", "conveyor01.ctrl"]},
]  # fmt: skip
BUSES = [
    {"name": "motion", "protocol": "canopen", "bitrate": "1 Mbit/s",
     "canopen": {"sync_period": ms(10), "sync_window": ms(10), "read_window": ms(10)},
     "description": "25 EPOS4 axes: velocity axes every SYNC, position axes every 2nd"},
    {"name": "plant", "protocol": "can", "bitrate": "500 kbit/s", "description": "line PLC field bus"},
    {"name": "cell", "protocol": "ftt-can", "bitrate": "1 Mbit/s", "ftt": {"ec": ms(5), "tm_size": 8, "lsw": ms(3)},
     "description": "machining cell"},
]  # fmt: skip


def build() -> Item:
    rng = random.Random(SEED)
    co_nodes, co_msgs, axes = canopen(rng)
    pl_nodes, pl_msgs = plant(rng, axes)
    ft_nodes, ft_msgs, triggers = ftt(rng)
    return {"buses": BUSES, "nodes": co_nodes + pl_nodes + ft_nodes, "messages": co_msgs + pl_msgs + ft_msgs,
            "triggers": triggers, "flows": FLOWS}  # fmt: skip


def flow(v: Any) -> str:
    """One value in YAML flow style."""
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {flow(x)}" for k, x in v.items()) + "}"
    if isinstance(v, list):
        return "[" + ", ".join(flow(x) for x in v) + "]"
    if isinstance(v, Hex):
        return f"0x{int(v):03X}"
    if isinstance(v, int):
        return str(v)
    plain = v.replace("_", "").replace(" ", "").replace(".", "").isalnum()
    return v if plain else json.dumps(v)


def render(spec: Item) -> str:
    lines = [
        "# GENERATED by benchmarks/make_large_spec.py: do not edit, change the script and run it again.",
        "# SYNTHETIC: a made-up production cell for benchmarks and regression tests, not a real installation.",
        "system: large_plant",
        "description: synthetic production cell, CANopen + plain CAN + FTT-CAN (benchmark spec)",
    ]
    for key in ("buses", "nodes", "messages", "triggers", "flows"):
        lines += ["", f"{key}:", *(f"  - {flow(item)}" for item in spec[key])]
    return "\n".join(lines) + "\n"


def main() -> None:
    spec = build()
    OUT.write_text(render(spec), encoding="utf-8")
    print(
        f"wrote specs/{OUT.name}: {len(spec['buses'])} buses, {len(spec['nodes'])} nodes, "
        f"{len(spec['messages'])} messages, {len(spec['triggers'])} triggers, {len(spec['flows'])} flows"
    )


if __name__ == "__main__":
    main()
