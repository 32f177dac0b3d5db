"""Floor 6, store: output folders, the I/O layer under every run.

    files.py       file names, atomic writes (a file is complete or absent), figures, PNG checks
    provenance.py  what ran, where and when: the run records in a manifest's ``runs``
    folder.py      the output folder: manifest and configuration, the lock, resume checks,
                   chunk files and the merge, the table's kept scenarios

Every floor above writes results through it; it knows nothing of how they are computed.
"""
