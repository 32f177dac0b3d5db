"""Floor 6, store: output folders, the I/O layer under every run (docs/outputs.md, "The output
folder of `sweep` and `table`"). docs/architecture.md, "The modules", maps its modules.

Every floor above writes results through it; it knows nothing of how they are computed.
"""
