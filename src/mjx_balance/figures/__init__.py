"""Floor 8, figures: matplotlib figures drawn from saved tables, one module per family.

    style.py       the one style: the outcome palette (colour-blind safe), the file format
                   (png, svg, pdf) and the paper sizes (one or two columns), save and subplots
    timeseries.py  a push's time series (angles, torques, CoP, CoM)
    region.py      the region map, the energy map, the robustness table's figure
    animation.py   the stick-figure GIF of one push
    cohort.py      a cohort's figures: area over height x mass, chosen subjects' boundaries,
                   one small outcome map per subject
    report.py      the report's figures: the weight study's bars, the conventions side by side,
                   the experiments' and studies' figures drawn into a report folder

Each function draws on the Axes it is given (or a new figure) and returns the Figure.
"""
