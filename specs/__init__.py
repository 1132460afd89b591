"""The example specs, shipped in the package as netcfg.examples: `netcfg init --from SYSTEM` starts from them."""
