"""netcfg.sim: a discrete-event simulator that executes a runtime.json (and nothing else)."""
