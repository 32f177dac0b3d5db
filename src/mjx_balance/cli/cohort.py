"""``mjx-balance cohort``: a population's region maps, one per subject, with the cohort's
table and figures (``api.cohort`` does the work; ``studies.cohort`` runs it).

The subjects come from one of three sources: a grid of bodies (``--heights`` and ``--masses``,
optionally ``--sexes``, ``--ankle-strengths``, ``--hip-strengths``: every combination), a CSV
file of real participants (``--subjects``) or a seeded sample (``--population N --seed S``)."""

from __future__ import annotations

import argparse
import logging
import math
from pathlib import Path
from typing import Any

from ..model.params import ParameterError
from ..studies.defaults import DEFAULT_SWEEP_DURATIONS, DEFAULT_SWEEP_FORCES  # light
from .common import base_config, guard_work, in_folder, progress_enabled, table_scenarios
from .options import (
    config_options,
    engine_options,
    queue_option,
    figure_options,
    finite_float,
    format_option,
    input_file,
    nonnegative_float,
    nonnegative_int,
    out_folder,
    positive_int,
    wait_option,
    write_exports,
    yes_option,
)

SEXES = ("male", "female")  # model.subject.SEXES (the parser stays light)


def add_parser(sub: Any) -> None:
    """The ``cohort`` sub-command (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser(
        "cohort",
        help="a population: every subject's region map, cohort.csv "
        "with each subject's recoverable area and the "
        "population's spread, and the cohort's figures",
    )
    _source_options(p)
    config_options(p)
    p.add_argument(
        "--forces",
        default=None,
        help=f"start:stop:step or a comma list [N] (default: the default sweep's, "
        f"{DEFAULT_SWEEP_FORCES})",
    )
    p.add_argument(
        "--durations",
        default=None,
        help="start:stop:step or a comma list [s] (default: the default sweep's, "
        f"{DEFAULT_SWEEP_DURATIONS})",
    )
    p.add_argument(
        "--table-forces",
        default=None,
        help="also each subject's table at these forces [N]: its max acting times "
        "and sustained-push limit in cohort.csv (default: no table)",
    )
    engine_options(p)
    queue_option(p, "subject", auto=True)
    wait_option(p)
    yes_option(p)
    format_option(p)
    figure_options(p)
    p.add_argument(
        "--out",
        type=out_folder,
        required=True,
        help="output folder: subjects/<id>/ (one sweep folder each), base/ (the "
        "base configuration's map), cohort.csv, cohort_summary.csv, "
        "cohort_probability.csv (P(recover) per cell with its 95 %% interval), "
        "cohort_probability_boundaries.csv, manifest.json, the figures",
    )
    p.set_defaults(target="mjx_balance.cli.cohort:cohort_command")


def _source_options(p: argparse.ArgumentParser) -> None:
    """The subjects' sources: a grid of bodies, a CSV file of participants or a population."""
    source = p.add_argument_group("subjects (one source)")
    source.add_argument(
        "--heights",
        default=None,
        metavar="GRID",
        help="statures [m]: start:stop:step or a comma list (with --masses; "
        "every combination of the lists is a subject)",
    )
    source.add_argument("--masses", default=None, metavar="GRID", help="body masses [kg]")
    source.add_argument(
        "--sexes",
        type=sexes,
        default=None,
        metavar="LIST",
        help="male, female or male,female (default: male)",
    )
    source.add_argument(
        "--ankle-strengths",
        default=None,
        metavar="GRID",
        help="factors on the mass-scaled ankle torque bound (default: 1)",
    )
    source.add_argument(
        "--hip-strengths",
        default=None,
        metavar="GRID",
        help="factors on the mass-scaled hip torque bound (default: 1)",
    )
    source.add_argument(
        "--ages",
        default=None,
        metavar="GRID",
        help="ages [yr]: each subject a person of that age and sex, strength and timing "
        "scaled from the base read as a young man's (--config human; docs/model.md, 'Age and "
        "sex'; default: no age, the base's strength scaled by mass)",
    )
    source.add_argument(
        "--subjects",
        type=input_file,
        default=None,
        metavar="FILE.csv",
        help="participants: a CSV file with columns height, mass and "
        "optionally id, sex, ankle_strength, hip_strength, age, notes (names "
        "in any case; lines starting with # are comments)",
    )
    _population_options(source)


def _population_options(source: Any) -> None:
    """``--population`` and its seed and distributions (an argument group of the sources)."""
    source.add_argument(
        "--population",
        type=positive_int,
        default=None,
        metavar="N",
        help="N subjects drawn at random (with --seed): sex, then height and "
        "mass from normal distributions truncated to a subject's ranges",
    )
    source.add_argument("--seed", type=nonnegative_int, default=None, help="the population's seed")
    source.add_argument(
        "--height-mean",
        type=finite_float,
        default=None,
        help="the population's mean stature [m] (default: 1.70)",
    )
    source.add_argument(
        "--height-sd",
        type=nonnegative_float,
        default=None,
        help="its standard deviation [m] (default: 0.09)",
    )
    source.add_argument(
        "--mass-mean",
        type=finite_float,
        default=None,
        help="the population's mean body mass [kg] (default: 70)",
    )
    source.add_argument(
        "--mass-sd",
        type=nonnegative_float,
        default=None,
        help="its standard deviation [kg] (default: 12)",
    )
    source.add_argument(
        "--female-fraction",
        type=nonnegative_float,
        default=None,
        help="probability that a subject is female (default: 0.5)",
    )
    source.add_argument(
        "--age-mean",
        type=finite_float,
        default=None,
        help="the population's mean age [yr]: subjects with ages (as --ages) drawn from a "
        "normal distribution truncated to 18-110 yr (default: no age)",
    )
    source.add_argument(
        "--age-sd",
        type=nonnegative_float,
        default=None,
        help="its standard deviation [yr] (with --age-mean; default: 0)",
    )


def sexes(text: str) -> list[str]:
    """A comma list of male / female."""
    items = [item.strip() for item in text.split(",") if item.strip()]
    bad = [item for item in items if item not in SEXES]
    if not items or bad:
        raise argparse.ArgumentTypeError(f"give male, female or male,female; got {text!r}")
    return items


def chosen_source(args: argparse.Namespace) -> str:
    """Which source the options name ("grid", "csv" or "population"); exactly one, complete
    (else ParameterError: exit code 2, before any work)."""
    if getattr(args, "subject", None) is not None:
        raise ParameterError(
            "--subject is one person; give a cohort's subjects with "
            "--heights and --masses, --subjects FILE.csv or --population N"
        )
    given = {
        "grid": args.heights is not None or args.masses is not None,
        "csv": args.subjects is not None,
        "population": args.population is not None,
    }
    named = [k for k, v in given.items() if v]
    if len(named) != 1:
        raise ParameterError(
            "give one source of subjects: --heights and --masses, "
            "--subjects FILE.csv or --population N --seed S"
            + (f" (got {', '.join(named)})" if named else "")
        )
    source = named[0]
    if source == "grid" and (args.heights is None or args.masses is None):
        raise ParameterError("--heights and --masses go together")
    if source == "population" and args.seed is None:
        raise ParameterError("--population needs --seed (the same seed, the same subjects)")
    grid_only = ("sexes", "ankle_strengths", "hip_strengths", "ages")
    stray = [n for n in grid_only if getattr(args, n) is not None and source != "grid"]
    if stray:
        raise ParameterError(f"--{stray[0].replace('_', '-')} goes with --heights and --masses")
    stray = [
        n
        for n in ("seed", *POPULATION_DEFAULTS)
        if getattr(args, n) is not None and source != "population"
    ]
    if stray:  # an option that would be ignored: the user meant something else
        raise ParameterError(f"--{stray[0].replace('_', '-')} goes with --population")
    if args.age_sd is not None and args.age_mean is None:
        raise ParameterError("--age-sd goes with --age-mean")
    return source


# --population's distributions when not given (studies.members.population's defaults)
POPULATION_DEFAULTS: dict[str, float | None] = {
    "height_mean": 1.70,
    "height_sd": 0.09,
    "mass_mean": 70.0,
    "mass_sd": 12.0,
    "female_fraction": 0.5,
    "age_mean": None,
    "age_sd": None,
}


MAX_SUBJECTS = 1_000_000  # even with --yes: one folder per subject


def subject_count(args: argparse.Namespace) -> int | None:
    """How many subjects the options give, without drawing or checking them: --population's
    N, the product of the grid's lists; None for a CSV file (read to count)."""
    from ..runs.grid import parse_grid  # lazy: the runs floor loads JAX

    source = chosen_source(args)
    if source == "population":
        return args.population
    if source == "csv":
        return None
    sizes = [
        parse_grid(args.heights, "--heights").size,
        parse_grid(args.masses, "--masses").size,
        len(args.sexes or ["male"]),
    ]
    for name in ("ankle_strengths", "hip_strengths", "ages"):
        option = getattr(args, name)
        sizes.append(parse_grid(option, f"--{name.replace('_', '-')}").size if option else 1)
    return math.prod(sizes)


def members_from(args: argparse.Namespace) -> list:
    """The cohort's subjects from the options (``studies.cohort``)."""
    from ..runs.grid import parse_grid  # lazy: the runs floor loads JAX
    from ..studies import members  # lazy: as above

    source = chosen_source(args)
    if source == "csv":
        return members.read_subjects(args.subjects)
    if source == "population":
        given: dict[str, Any] = {
            k: v if getattr(args, k) is None else getattr(args, k)
            for k, v in POPULATION_DEFAULTS.items()
        }
        return members.population(args.population, args.seed, **given)
    return members.subject_grid(
        parse_grid(args.heights, "--heights"),
        parse_grid(args.masses, "--masses"),
        args.sexes or ["male"],
        parse_grid(args.ankle_strengths, "--ankle-strengths") if args.ankle_strengths else [1.0],
        parse_grid(args.hip_strengths, "--hip-strengths") if args.hip_strengths else [1.0],
        parse_grid(args.ages, "--ages") if args.ages else [None],
    )


def subject_setup(count: int) -> tuple[tuple[float, str], tuple[float, str]]:
    """The plan's set-up of ``count`` subjects (``guard_work``'s ``setup``, ``during``):
    before the first scenario, the subjects checked before the folder is made
    (``studies.cohort.checked_first``) and the first queue's maps set up; during the run,
    every other map's (the base body's too): its closed loop built when its queue starts, its
    folder written after."""
    from ..runs.chunks import SUBJECT_CHECK_SECONDS, SUBJECT_SETUP_SECONDS  # lazy: JAX
    from ..runs.population import FIRST_QUEUE  # lazy: as above
    from ..studies.cohort import checked_first  # lazy: as above

    checked, first = checked_first(count), min(count + 1, FIRST_QUEUE)
    return (
        (
            checked * SUBJECT_CHECK_SECONDS + first * SUBJECT_SETUP_SECONDS,
            f"checking {checked:,} subjects' configurations and setting up {first} maps",
        ),
        (
            (count + 1 - first) * SUBJECT_SETUP_SECONDS,
            f"setting up {count + 1 - first:,} more maps (each one's closed loop built, its "
            "folder written)",
        ),
    )


def cohort_command(args: Any) -> int:
    """Every subject's region map in OUT/subjects/<id>/, then cohort.csv, the summary and the
    figures. Everything is checked (the subjects, the grids, every subject's configuration, a
    folder holding another cohort's results) before the folder is made or locked."""
    from ..model.config_files import with_convention  # lazy: not for --help
    from ..runs import DEFAULT_SWEEP  # lazy: the runs floor loads JAX; not for --help
    from ..studies.cohort import plan_cohort, run_plan  # lazy: as above
    from ..studies.probability import interval_text  # lazy: as above

    from ..runs.grid import grid_values  # lazy: as above

    base = with_convention(base_config(args), args.convention)
    given = {
        k: DEFAULT_SWEEP[k] if getattr(args, k) is None else getattr(args, k)
        for k in ("forces", "durations")
    }  # an empty value is refused, not the default
    forces = grid_values(given["forces"], "forces")
    durations = grid_values(given["durations"], "durations")
    tables = None if args.table_forces is None else grid_values(args.table_forces, "table forces")
    # The work is planned (and absurd work refused) before the subjects are drawn or checked:
    # a population's count is known from the options, a grid's from its values.
    members, count = None, subject_count(args)
    if count is None:  # a CSV file: read to count
        members = members_from(args)
        count = len(members)
    # the subjects' maps and the base body's (the probability figure's reference boundary)
    setup, during = subject_setup(count)
    guard_work(
        args,
        base,
        (count + 1) * forces.size * durations.size,
        "cells",
        extra=0 if tables is None else count * table_scenarios(base, tables.size),
        note=interval_text(count),
        setup=setup,
        during=during,
    )
    if count > MAX_SUBJECTS:
        raise ParameterError(
            f"{count:,} subjects is more than a cohort may hold "
            f"({MAX_SUBJECTS:,}: a folder each); run it in parts"
        )
    if members is None:
        members = members_from(args)
    out = Path(args.out)
    say = logging.getLogger("mjx_balance").info
    plan = plan_cohort(
        out,
        members,
        base,
        forces,
        durations,
        table_forces=tables,
        say=say,
        slots=args.slots,
        full_length=args.full_length,
        physics=args.physics or "auto",
        queue=args.queue,
    )

    def work() -> None:
        run_plan(plan, progress=progress_enabled(args), say=say)
        write_exports(out, args)

    return in_folder(out, work, wait=getattr(args, "wait", False))
