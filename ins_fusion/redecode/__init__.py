"""``gnss_ins redecode``: a recording's raw topics through today's drivers (docs/redecode.md)."""
