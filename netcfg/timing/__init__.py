"""The timing core: frame lengths, stuffing, EC arithmetic, Ethernet frame times (frames.py) and the analyses
built on them. Every other part of netcfg asks this package, never re-derives a formula."""
