"""netcfg: a declarative control-network configuration compiler."""

__version__ = "0.1.0"
