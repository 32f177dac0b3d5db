"""Floor 9, studies: experiments built from runs, each resumable in its own folder.

    catalog.py      the studies beyond the paper (variants, numbers, readings)
    experiments.py  the paper's experiments and the studies, run into a report folder (plans)
    compare.py      several configurations on one grid
    landscape.py    the weight landscape (Q x R scales, with and without delay)
    sensitivity.py  the robustness table under every reading of the study
    basin.py        the recovery basin over initial CoM states
    cohort.py       a population's region maps, one per subject, and its numbers
"""
