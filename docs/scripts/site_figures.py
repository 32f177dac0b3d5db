"""Draw every figure of the documentation site (docs/figures/) again, each by the command whose
output it is, as the site's pages (docs/study.md, docs/people.md, ...) give the command beside
the figure.

    python docs/scripts/site_figures.py [--only NAME[,NAME...]] [--work /tmp/site_figures]

Each figure is the package's own drawing: the command runs into a work folder and the file it
writes is copied to docs/figures/ (never edited). The whole set takes about an hour on a 2-core
CPU (the people cohorts and the basins are the longest); ``--only`` redraws some.
``tests/package/test_site_figures.py`` checks that every figure in docs/figures/ is one of these.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
FIGURES = REPO / "docs" / "figures"
MB = [sys.executable, "-m", "mjx_balance", "-q"]
HUMAN_GRID = ["--forces", "0:250:25", "--durations", "0.1,0.15,0.2,0.3,0.4,0.6,1.0"]

# figure -> (the command, OUT standing for its work folder; the file it writes under OUT)
COMMANDS: dict[str, tuple[list[str], str]] = {
    "basin.png": ([*MB, "basin", "--out", "OUT", "--yes"], "basin.png"),
    "cohort_probability.png": (
        [*MB, "cohort", "--population", "6", "--seed", "1", "--forces", "0:150:10",
         "--durations", "0.05,0.1,0.2,0.3,0.5,1", "--out", "OUT", "--yes"],
        "cohort_probability.png",
    ),
    "landscape.png": (
        [*MB, "landscape", "--sweep", "landscape_weights", "--delays", "0,100c", "--out", "OUT",
         "--yes"],
        "landscape.png",
    ),
    "sensitivity.png": ([*MB, "sensitivity", "--out", "OUT", "--yes"], "sensitivity.png"),
    "stepping_human.png": (
        [*MB, "sweep", "--config", "human", "--forces", "0:300:20", "--durations",
         "0.05,0.1,0.2,0.3,0.5,1.0,1.5,2.0", "--out", "OUT", "--yes"],
        "region.png",
    ),
    "people_basin_fsr.png": (
        [sys.executable, str(REPO / "docs" / "scripts" / "basin_fsr.py"), "OUT"], "basin_fsr.png"
    ),
    "people_cohort_young.png": (
        [*MB, "cohort", "--config", "human", "--population", "20", "--seed", "1",
         "--female-fraction", "0", *HUMAN_GRID, "--out", "OUT", "--yes"],
        "cohort_probability.png",
    ),
    "people_cohort_older.png": (
        [*MB, "cohort", "--config", "human_older", "--population", "20", "--seed", "1",
         "--female-fraction", "0", *HUMAN_GRID, "--out", "OUT", "--yes"],
        "cohort_probability.png",
    ),
    "people_cohort_ages_young.png": (
        [*MB, "cohort", "--config", "human", "--population", "20", "--seed", "1",
         "--age-mean", "25", "--age-sd", "3", *HUMAN_GRID, "--out", "OUT", "--yes"],
        "cohort_probability.png",
    ),
    "people_cohort_ages_older.png": (
        [*MB, "cohort", "--config", "human", "--population", "20", "--seed", "1",
         "--age-mean", "75", "--age-sd", "5", *HUMAN_GRID, "--out", "OUT", "--yes"],
        "cohort_probability.png",
    ),
}


def draw(name: str, work: Path) -> Path:
    """Run ``name``'s command into ``work/<name>`` and copy the figure it writes."""
    command, written = COMMANDS[name]
    out = work / Path(name).stem
    argv = [str(out) if a == "OUT" else a for a in command]
    print(f"{name}: {' '.join(argv)}", flush=True)
    subprocess.run(argv, check=True, cwd=REPO)
    target = FIGURES / name
    shutil.copyfile(out / written, target)
    return target


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="", help="comma list of figure names (default: all)")
    parser.add_argument("--work", type=Path, default=Path("/tmp/site_figures"))
    args = parser.parse_args()
    names = [n for n in args.only.split(",") if n] or list(COMMANDS)
    unknown = [n for n in names if n not in COMMANDS]
    if unknown:
        parser.error(f"unknown figure(s) {', '.join(unknown)}; known: {', '.join(COMMANDS)}")
    for name in names:
        print(f"wrote {draw(name, args.work)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
