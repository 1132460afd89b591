"""Editor support: `netcfg lsp`, a language server (netcfg.lsp.server, on pygls), and what it knows about a spec's
text (netcfg.lsp.document). Nothing here is imported by `import netcfg` or by `netcfg check`."""
