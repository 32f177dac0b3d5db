"""Floor 2, measures: what a closed loop's motion means, written once for every path.

    outcomes.py  the outcome rules (fall, settle, recovery), outcome codes, the summary columns
    metrics.py   the per-scenario summary (peaks, extremes, energies) from recorded samples
    units.py     the unit of every column the product writes (parquet metadata, CSV sidecars)
"""
