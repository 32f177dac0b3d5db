"""Floor 6, store: output folders, the I/O layer under every run.

    folder.py  atomic writes, the manifest and its provenance, locks, chunk files, the merge,
               resume checks

Every floor above writes results through it; it knows nothing of how they are computed.
"""
