"""Measurement and its results: metrics of runs against references, the tidy
summary, speed-ups, tables, counters, the variance regression check, and the
sweep pipeline with its console report.

May import core/, experiment/, execution/ and reference/."""
