"""Drives that rebooted while the live master cycles (on_reboot: recover): set up again on a worker thread beside
the cycle, with the set-up's own steps, then enabled over SDO or their PDOs (netcfg.runtime.operate)."""

from __future__ import annotations

import threading

import can
import canopen
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from netcfg.runtime.canopen_setup import configure_node
from netcfg.runtime.cia402 import Cia402Error, PdoEnabler, enable_operation
from netcfg.runtime.operate_state import Operation, Recovery, sdo_io
from netcfg.runtime.supervision import Event


class RecoveringOperation(Operation):
    """An operation that sets rebooted drives up again while it cycles."""

    def _recover(self, name: str, booted: float) -> None:
        """Set the node up again (the set-up's own code path: identity, PDOs, start-up values, read-back, NMT start)
        and, over SDO, enable its CiA 402 power state machine, on a worker thread while the others cycle."""
        node_cfg = self.cfg.node(name)
        assert node_cfg.node_id is not None
        rec = Recovery(name, booted, canopen.Network(self.bus))
        self.sdo_routes[0x580 + node_cfg.node_id] = rec  # CiA 301 default SDO server -> client COB-ID
        self.recovering[name] = rec
        outcome = self.out.nodes[name]

        def work() -> None:
            try:
                setup = configure_node(
                    self.cfg, rec.network, node_cfg, bus=self.co_bus, sdo_timeout_s=self.plan.sdo_timeout_s
                )
                if not setup.ok:
                    rec.error = f"set-up again failed at {setup.step}: {setup.error}"
                elif outcome.cia402_over == "SDO":
                    remote = self._remote(rec.network, node_cfg.node_id or 0)
                    try:
                        rec.path = enable_operation(name, *sdo_io(remote), timeout_s=self.plan.transition_timeout_s)
                    finally:
                        del rec.network[node_cfg.node_id or 0]
            except (Cia402Error, SdoAbortedError, SdoCommunicationError, can.CanError) as exc:
                rec.error = f"enabling again failed: {exc}"
            finally:
                rec.done = self.clock.now()

        rec.thread = threading.Thread(target=work, name=f"netcfg-recover-{name}", daemon=True)
        rec.thread.start()

    def _poll_recoveries(self) -> None:
        """Recoveries that ended: a "recovered" event, or "recovery-failed" with the node's on_loss."""
        assert self.supervisor is not None and self.master is not None
        for name, rec in list(self.recovering.items()):
            if rec.done is None:
                continue
            enabler = self.enablers.get(name)
            if rec.error is None and self.out.nodes[name].cia402_over == "PDO":
                if enabler is None or enabler.error is not None:  # configured and started: now its PDO walk
                    self.enablers[name] = PdoEnabler(name, self.timeout_cycles)
                    self.master.muted.discard(name)
                    continue
                if not enabler.enabled:
                    continue
                rec.path = list(enabler.path)
            del self.recovering[name]
            self.sdo_routes = {k: v for k, v in self.sdo_routes.items() if v is not rec}
            node = self.out.nodes[name]
            took_ms = 1e3 * (rec.done - rec.booted)
            if rec.error is None:
                self.master.muted.discard(name)
                self.supervisor.quiet.discard(name)
                text = (
                    f"{name} recovered {took_ms:.1f} ms after its boot-up: identity checked, configuration written "
                    f"and read back, started, {' -> '.join(rec.path) or 'OPERATIONAL'}"
                )
                self.supervisor.events.append(Event(rec.done, name, "recovered", "continue", text))
                node.state = rec.path[-1] if rec.path else "OPERATIONAL"
            else:
                action = self.cfg.node(name).on_loss
                text = f"{name} not recovered ({took_ms:.1f} ms after its boot-up): {rec.error}"
                self.supervisor.events.append(Event(rec.done, name, "recovery-failed", action, text))
                node.errors.append(rec.error)
            node.reboots[-1].update(
                recovered_at_s=round(rec.done - (self.first or 0.0), 6) if rec.error is None else None,
                recovery_ms=round(took_ms, 3),
                result="recovered" if rec.error is None else rec.error,
            )

    def _finish_recoveries(self) -> None:
        """The cycle ended with a recovery under way: keep handing it its SDO answers until it ends."""
        for rec in list(self.recovering.values()):
            while rec.thread is not None and rec.thread.is_alive():
                frame = self.bus.recv(timeout=0.01)
                if frame is not None:
                    self._on_frame(frame, self.clock.now())
            if rec.done is not None and rec.error is None and self.out.nodes[rec.node].cia402_over == "PDO":
                rec.error = "the run ended before its CiA 402 walk over PDOs"
        if self.supervisor is not None and self.master is not None:
            self._poll_recoveries()
            while len(self.out.events) < len(self.supervisor.events):
                event = self.supervisor.events[len(self.out.events)]
                self.out.events.append((event.time - (self.first or 0.0), event))
