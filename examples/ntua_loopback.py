"""Seed 001 on one machine: the PC endpoint and stand-in MCUs exchange commands and encoder frames over loopback.

    python examples/ntua_loopback.py                        # SAHR from generated/, 1,000 pairs (about 1 s)
    python examples/ntua_loopback.py generated/ntua_sahr/runtime.json --pairs 10000
    python examples/ntua_loopback.py generated/ntua_treadmill/runtime.json --pairs 2000 --net 127.0.1

Every MCU that consumes a PC command answers it with an echo (so each pair is matched by sequence number); every
other MCU streams its messages at their configured rate, as on the robot. Commands are paced at their configured
period unless --period-us is given. Prints the round-trip distribution of each command/answer pair.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

import netcfg.runtime as rt
from netcfg.runtime.udp import PcEndpoint, StandInMcu, exchange, loopback_hosts

SAHR = Path(__file__).resolve().parent.parent / "generated" / "ntua_sahr" / "runtime.json"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runtime", type=Path, nargs="?", default=SAHR,
                        help="a runtime.json of an Ethernet/UDP system (default: the SAHR robot's in generated/)")
    parser.add_argument("--pc", default="pc", help="the PC's node name (default: pc)")
    parser.add_argument("--pairs", type=int, default=1_000, help="commands to send per command message (default 1000)")
    parser.add_argument("--period-us", type=float, help="pace commands at this period instead of the configured one")
    parser.add_argument("--net", default="127.0.0", help="first three octets of the loopback addresses to use")
    parser.add_argument("--quiet-mcus", action="store_true", help="do not stream the MCUs that take no commands")
    args = parser.parse_args(argv)

    cfg = rt.load(args.runtime)
    hosts = loopback_hosts(cfg, args.net)
    with contextlib.ExitStack() as stack:  # stops the MCUs and closes every socket, whatever happens
        pc = stack.enter_context(PcEndpoint(cfg, args.pc, hosts))
        commands = pc.produces
        commanded = {c for m in commands for c in m.consumers}
        streaming = set() if args.quiet_mcus else {m.producer for m in pc.consumes} - commanded
        mcus = [stack.enter_context(StandInMcu(cfg, n, hosts)) for n in sorted(commanded)]
        mcus += [stack.enter_context(StandInMcu(cfg, n, hosts, periodic=True)) for n in sorted(streaming)]
        for cmd in commands:
            for consumer in cmd.consumers:
                answer = next(m for m in mcus if m.endpoint.node.name == consumer).answer
                if answer is None:
                    print(f"{cmd.name} -> {consumer}: {consumer} sends nothing back; skipped")
                    continue
                period = None if args.period_us is None else round(args.period_us * 1000)
                result = exchange(pc, cmd.name, answer.name, args.pairs, period_ns=period)
                matched = sum(p.matched for p in result.pairs)
                first, last = result.pairs[0].t_send_ns, result.pairs[-1].t_send_ns
                rate = (len(result.pairs) - 1) / ((last - first) / 1e9) if last > first else float("nan")
                print(
                    f"{cmd.name} -> {answer.name}: {matched}/{len(result.pairs)} matched at {rate:.1f} Hz "
                    f"(configured {cmd.rate_hz} Hz); other frames meanwhile: {dict(result.others) or 'none'}"
                )
                print(f"  round trip: {result.rtt()}")
        print(f"PC counters: {pc.counters}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
