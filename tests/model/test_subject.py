"""Subjects: a person's body from de Leva (1996) Table 4, the segment inertias as
parameters, and the linked limits every configuration is checked against.

The hand-worked subject below writes out the arithmetic with the published table's numbers
(de Leva 1996, J Biomech 29(9):1223-1230, Table 4, males: reference stature 1741 mm), not the
package's own table read back, so a wrong digit or a wrong aggregation in model/subject.py fails.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json

import numpy as np
import pytest
from support import REPO

import mjx_balance as mb
from mjx_balance import cli
from mjx_balance.cli.main import build_parser
from mjx_balance.model.linear import linear_model
from mjx_balance.model.mjcf import mjcf
from mjx_balance.model.params import (
    BodyParams,
    Config,
    ParameterError,
    ParameterWarning,
    config_warnings,
)
from mjx_balance.model.config_files import load_config, run_config
from mjx_balance.model.subject import Subject, parse_subject, with_sections
from mjx_balance.runs.definitions import load_sweep
from mjx_balance.store.folder import OutputFolder, folder_lock, record_simulation

SWEEPS = REPO / "sweeps"
# The same arithmetic done in another order: a few float64 roundings apart.
REL = 1e-12


def _male_175_70() -> dict[str, float]:
    """Male, 1.75 m, 70 kg, by hand from de Leva (1996) Table 4 (lengths in mm / 1000 at the
    reference stature 1.741 m, masses %, CoM % from the origin endpoint, sagittal r %)."""
    s = 1.75 / 1.741
    # foot (HEEL-TTIP 258.1 mm, 1.37 %, r 25.7 %): both feet
    foot_mass = 2 * 0.0137 * 70
    foot_length = 0.2581 * s
    foot_inertia = foot_mass * (0.257 * foot_length) ** 2
    # lower body: shank (KJC-LMAL 434.0 mm, 4.33 %, CoM 44.59 % from the knee, r 25.5 %) and
    # thigh (HJC-KJC 422.2 mm, 14.16 %, CoM 40.95 % from the hip, r 32.9 %), two of each
    shank, thigh = 0.4340 * s, 0.4222 * s
    lower_length = shank + thigh
    m_sh, m_th = 2 * 0.0433 * 70, 2 * 0.1416 * 70
    z_sh = shank - 0.4459 * shank  # above the ankle
    z_th = lower_length - 0.4095 * thigh
    lower_mass = m_sh + m_th
    lower_com = (m_sh * z_sh + m_th * z_th) / lower_mass
    lower_inertia = (
        m_sh * (0.255 * shank) ** 2
        + m_th * (0.329 * thigh) ** 2
        + m_sh * (z_sh - lower_com) ** 2
        + m_th * (z_th - lower_com) ** 2
    )
    # upper body above the hip: trunk (SUPR-MIDH 531.9 mm, 43.46 %, CoM 44.86 % from SUPR,
    # r 37.2 %), head (VERT-MIDG 203.3 mm, 6.94 %, CoM 59.76 % from the vertex, r 36.2 %) at
    # the top, arms hanging from the trunk's top: upper arm (281.7 mm, 2.71 %, 57.72 %,
    # r 28.5 %), forearm (268.9 mm, 1.62 %, 45.74 %, r 27.6 %), hand (86.2 mm, 0.61 %,
    # 79.00 %, r 62.8 %), two of each
    upper_length = 1.75 - lower_length
    trunk, head, arm, forearm, hand = (0.5319 * s, 0.2033 * s, 0.2817 * s, 0.2689 * s, 0.0862 * s)
    parts = [  # (mass, height above the hip, own pitch inertia)
        (0.4346 * 70, trunk * (1 - 0.4486), 0.4346 * 70 * (0.372 * trunk) ** 2),
        (0.0694 * 70, upper_length - 0.5976 * head, 0.0694 * 70 * (0.362 * head) ** 2),
        (2 * 0.0271 * 70, trunk - 0.5772 * arm, 2 * 0.0271 * 70 * (0.285 * arm) ** 2),
        (2 * 0.0162 * 70, trunk - arm - 0.4574 * forearm, 2 * 0.0162 * 70 * (0.276 * forearm) ** 2),
        (
            2 * 0.0061 * 70,
            trunk - arm - forearm - 0.79 * hand,
            2 * 0.0061 * 70 * (0.628 * hand) ** 2,
        ),
    ]
    upper_mass = sum(m for m, _, _ in parts)
    upper_com = sum(m * z for m, z, _ in parts) / upper_mass
    upper_inertia = sum(i + m * (z - upper_com) ** 2 for m, z, i in parts)
    return {
        "foot_mass": foot_mass,
        "foot_length": foot_length,
        "foot_inertia": foot_inertia,
        "lower_mass": lower_mass,
        "lower_length": lower_length,
        "lower_com": lower_com,
        "lower_inertia": lower_inertia,
        "upper_mass": upper_mass,
        "upper_length": upper_length,
        "upper_com": upper_com,
        "upper_inertia": upper_inertia,
    }


def test_a_subject_worked_by_hand_from_the_table():
    expected = _male_175_70()
    body = Subject(1.75, 70).config().body
    for name, value in expected.items():
        assert getattr(body, name) == pytest.approx(value, rel=REL), name
    # the segments' masses are the whole body (the table's male fractions sum to 100.00 %)
    assert body.total_mass == pytest.approx(70.0, rel=REL)
    # a few of the numbers, to the table's precision, as docs/model.md quotes them
    assert body.lower_mass == pytest.approx(25.886, abs=1e-9)
    assert body.upper_mass == pytest.approx(42.196, abs=1e-9)


def test_a_subjects_bounds():
    foot = _male_175_70()["foot_length"]
    ctrl = Subject(1.75, 70, ankle_strength=0.6, hip_strength=0.8).config().controller
    assert ctrl.cop_bounds == pytest.approx((-foot / 2, foot / 2), rel=REL)
    assert ctrl.com_bounds == pytest.approx((-foot / 2, foot / 2), rel=REL)
    # the study's +-20 / +-100 N m on its 66.3-kg body, times 70 / 66.3 and the strengths
    assert ctrl.input1_bounds == pytest.approx(
        (-20 * 70 / 66.3 * 0.6, 20 * 70 / 66.3 * 0.6), rel=REL
    )
    assert ctrl.input2_bounds == pytest.approx(
        (-100 * 70 / 66.3 * 0.8, 100 * 70 / 66.3 * 0.8), rel=REL
    )
    # a female subject uses the female columns (foot 228.3 mm at 1.735 m, 1.29 %)
    female = Subject(1.60, 55, "female").config().body
    assert female.foot_length == pytest.approx(0.2283 * 1.60 / 1.735, rel=REL)
    assert female.foot_mass == pytest.approx(2 * 0.0129 * 55, rel=REL)


def test_the_default_body_is_unchanged():
    body = BodyParams()
    # None means the uniform shapes, bitwise as before the inertias were parameters
    assert body.lower_inertia is None and body.upper_inertia is None and body.foot_inertia is None
    assert body.lower_pitch_inertia == 30.0 * 1.0**2 / 12.0
    assert body.upper_pitch_inertia == 35.0 * 0.6**2 / 12.0
    assert body.foot_pitch_inertia == 1.3 * (0.30**2 + 0.02**2) / 12.0
    # the default configuration's record (manifests, resume checks) has no new keys: its hash
    # is the one computed with the package before this change
    text = json.dumps(Config().to_dict(), sort_keys=True)
    assert hashlib.sha256(text.encode()).hexdigest() == (
        "c3c4c7f3f16787cc4af28fe08f527936c926b38aee308c5dcf663d8eb0a72934"
    )
    assert "inertia" not in text
    # the same numbers given explicitly build the same MJCF and the same linear model, bitwise
    given = Config().replace(
        body={
            "lower_inertia": 30.0 / 12.0,
            "upper_inertia": 35 * 0.36 / 12,
            "foot_inertia": body.foot_pitch_inertia,
        }
    )
    assert mjcf(given.body) == mjcf(body)
    for convention in ("paper", "joint"):
        a = linear_model(body, convention, 0.01)
        b = linear_model(given.body, convention, 0.01)
        assert np.array_equal(a.A, b.A) and np.array_equal(a.B, b.B)


def test_a_given_inertia_reaches_the_models():
    config = Config().replace(body={"upper_inertia": 2.0})
    assert 'diaginertia="2 2 0.002"' in mjcf(config.body)
    # M_abs[1, 1] = I2 + m2 c2^2 in the linear model: a larger I2 slows the upper body
    assert not np.array_equal(
        linear_model(config.body, "paper", 0.01).A, linear_model(BodyParams(), "paper", 0.01).A
    )
    with pytest.raises(ParameterError, match=r"body.upper_inertia = -1"):
        Config().replace(body={"upper_inertia": -1.0})
    with pytest.raises(ParameterError, match=r"body.lower_inertia = 'big'"):
        Config().replace(body={"lower_inertia": "big"})


def test_a_subject_body_builds_in_mujoco():
    from mjx_balance.model.mjcf import build_model

    for subject in (Subject(1.75, 70), Subject(1.60, 55, "female"), Subject(1.0, 16)):
        model = build_model(subject.config().body)
        assert model.nbody == 4


# -- linked limits ---------------------------------------------------------------------------


def test_contradicting_limits_are_refused_naming_both():
    with pytest.raises(ParameterError) as err:
        Config().replace(controller={"com_bounds": [0.2, 0.3]})
    assert "controller.com_bounds = [0.2, 0.3]" in str(err.value)
    assert "body.foot_length = 0.3" in str(err.value)
    with pytest.raises(ParameterError) as err:
        Config().replace(controller={"cop_bounds": [-0.4, -0.2]})
    assert "controller.cop_bounds = [-0.4, -0.2]" in str(err.value)
    with pytest.raises(ParameterError) as err:
        Config().replace(controller={"input1_bounds": [0, 0], "input2_bounds": [0, 0]})
    assert "controller.input1_bounds = [0, 0]" in str(err.value)
    assert "controller.input2_bounds = [0, 0]" in str(err.value)
    # one motor off is a deliberate study (the ankle-only strategy), not a contradiction
    Config().replace(controller={"input2_bounds": [0, 0]})


@pytest.mark.parametrize(
    "name", ["input1_bounds", "input2_bounds", "state1_bounds", "state2_bounds"]
)
@pytest.mark.parametrize("bounds", [[5, 20], [-20, -5], [1e300, 1e300], [-1e300, -1e300]])
def test_a_bound_that_excludes_rest_is_refused(name, bounds):
    """An input or angle bound without 0 (the upright rest's value) is refused by name (was:
    [1e300, 1e300] passed every check and the scalar reference's OSQP set-up raised a
    traceback; [5, 20] ran pushes from a rest the body cannot hold)."""
    with pytest.raises(ParameterError) as err:
        Config().replace(controller={name: bounds})
    assert f"controller.{name} = [{bounds[0]:g}, {bounds[1]:g}]" in str(err.value)
    assert "excludes 0" in str(err.value)
    Config().replace(controller={name: [min(bounds[0], 0), max(bounds[1], 0)]})  # with 0: kept


def test_a_never_binding_limit_warns_and_is_in_the_manifest(tmp_path):
    with pytest.warns(ParameterWarning, match=r"cop_bounds = \[-0.2, 0.2\].*foot_length = 0.3"):
        config = Config().replace(controller={"cop_bounds": [-0.2, 0.2]})
    assert len(config_warnings(config)) == 1
    with folder_lock(tmp_path / "sweep"):
        manifest = OutputFolder(tmp_path / "sweep", config).open()
    assert manifest["config_warnings"] == config_warnings(config)
    assert json.loads((tmp_path / "sweep" / "manifest.json").read_text())["config_warnings"]
    (tmp_path / "sim").mkdir()
    record_simulation(tmp_path / "sim", config, [0.0], [0.1])
    saved = json.loads((tmp_path / "sim" / "manifest.json").read_text())
    assert saved["config_warnings"] == config_warnings(config)
    # a configuration without one has no such key
    with folder_lock(tmp_path / "plain"):
        assert "config_warnings" not in OutputFolder(tmp_path / "plain", Config()).open()


def test_the_default_and_every_shipped_sweep_pass_the_linked_limits(recwarn):
    assert config_warnings(Config()) == []
    for path in sorted(SWEEPS.glob("*.toml")):
        definition = load_sweep(path, Config())
        assert config_warnings(definition.config) == [], path
    assert not [w for w in recwarn if issubclass(w.category, ParameterWarning)]


# -- entry points ----------------------------------------------------------------------------


def test_a_subject_table_in_a_config_file(tmp_path):
    path = tmp_path / "me.toml"
    path.write_text(
        '[subject]\nheight = 1.6\nmass = 55\nsex = "female"\n\n[body]\nfriction = 0.8\n'
    )
    config = load_config(path)
    assert config.body == dataclasses.replace(
        Subject(1.6, 55, "female").config().body, friction=0.8
    )
    # --subject replaces the file's [subject]; --set goes on top of the subject's values
    other = run_config(path, None, ["body.lower_mass=20"], Subject(1.8, 80))
    assert other.body.foot_length == Subject(1.8, 80).config().body.foot_length
    assert other.body.lower_mass == 20.0 and other.body.friction == 0.8
    # a value the subject derives, given beside it in the same file: refused naming both
    path.write_text("[subject]\nheight = 1.6\nmass = 55\n\n[body]\nlower_mass = 33.0\n")
    with pytest.raises(ParameterError) as err:
        load_config(path)
    assert "body.lower_mass = 33.0" in str(err.value)
    assert "subject height=1.6,mass=55" in str(err.value)
    # a sweep definition may carry a subject too (Config.replace's subject)
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('[subject]\nheight = 1.6\nmass = 55\n\n[sweep]\nforces = "0:10:10"\n')
    assert load_sweep(sweep, Config()).config == Subject(1.6, 55).config()


def test_subject_to_config_and_the_api():
    subject = mb.Subject(height=1.62, mass=58, sex="female")
    assert "Subject" in mb.__all__
    config = subject.config()
    assert config == Subject(1.62, 58, "female").config(Config())
    from mjx_balance.api import as_config

    assert as_config(subject) == config
    # a base's other values are kept
    base = Config().replace(scenario={"t_end": 6.0})
    assert subject.config(base).scenario.t_end == 6.0


@pytest.mark.parametrize(
    "text, words",
    [
        ("height=abc,mass=58", "height='abc' is not a number"),
        ("height=1.62", "give mass"),
        ("height=-1.62,mass=58", "subject.height = -1.62"),
        ("height=1.62,mass=58,sex=other", "subject.sex = 'other'"),
        ("height=1.62,mass=58,weight=80", "unknown key(s) weight"),
        ("height=1.62,mass=58,age=8", "subject.age = 8"),
        ("height:1.62,mass=58", "is not KEY=VALUE"),
        ("height=1.62,mass=58,ankle_strength=0", "subject.ankle_strength = 0"),
    ],
)
def test_bad_subjects_are_refused(text, words):
    with pytest.raises(ParameterError) as err:
        parse_subject(text)
    assert words in str(err.value)


def test_the_subject_flag_on_every_command_with_set(capsys, tmp_path):
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    with_set = []

    def walk(p: argparse.ArgumentParser, name: str) -> None:
        flags = {o for a in p._actions for o in a.option_strings}
        if "--set" in flags:
            with_set.append(name)
            assert "--subject" in flags, name
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for child, child_parser in a.choices.items():
                    walk(child_parser, f"{name} {child}")

    for name, p in sub.choices.items():
        walk(p, name)
    assert {"simulate", "sweep", "table", "compare"} <= set(with_set)
    args = parser.parse_args(
        ["sweep", "--subject", "height=1.62,mass=58,sex=female", "--out", str(tmp_path / "o")]
    )
    assert args.subject == Subject(1.62, 58, "female")
    try:
        code = cli.main(["sweep", "--subject", "height=abc,mass=58", "--out", str(tmp_path / "o")])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and "--subject" in err and "height='abc' is not a number" in err


def test_subjects_from_a_csv(tmp_path):
    from mjx_balance.model.subject import subjects_from_csv

    path = tmp_path / "cohort.csv"
    path.write_text("id,height,mass,sex\np1,1.62,58,female\np2,1.80,82,male\n")
    assert subjects_from_csv(path) == [Subject(1.62, 58, "female"), Subject(1.80, 82)]
    path.write_text("height,mass\n1.7,abc\n")
    with pytest.raises(ParameterError, match=r"line 2.*mass"):
        subjects_from_csv(path)


def test_the_layers_over_a_subject(tmp_path):
    """--subject under a sweep definition (its explicit values win) and compare's variants
    (a variant file with a [subject] goes on the base)."""
    from mjx_balance.cli.common import base_config
    from mjx_balance.studies.compare import load_one

    subject = Subject(1.6, 55, "female")
    args = argparse.Namespace(config=None, set=None, subject=subject)
    definition = load_sweep(SWEEPS / "study_weak_ankle.toml", base_config(args, overrides=False))
    assert definition.config.body == subject.config().body
    assert definition.config.controller.input1_bounds == (-12.0, 12.0)  # the file's, unscaled
    assert definition.config.controller.input2_bounds == subject.config().controller.input2_bounds
    variant = tmp_path / "variant.toml"
    variant.write_text('[subject]\nheight = 1.6\nmass = 55\nsex = "female"\n')
    base = Config().replace(scenario={"t_end": 6.0})
    assert load_one(variant, base) == subject.config(base)


def test_a_command_says_a_never_binding_limit_once(tmp_path, capsys):
    code = cli.main(
        ["model", "--set", "controller.cop_bounds=[-0.2, 0.2]", "--out", str(tmp_path / "body.xml")]
    )
    err = capsys.readouterr().err
    assert code == 0
    assert err.count("cop_bounds = [-0.2, 0.2]") == 1, err


# --- a subjects CSV file: its columns, its rows, and the bounds every path shares -----------


def _csv(tmp_path, text: str, encoding: str = "utf-8"):
    path = tmp_path / "people.csv"
    path.write_text(text, encoding=encoding)
    return path


def test_csv_headers_match_ignoring_case_spaces_and_an_excel_bom(tmp_path):
    """`Sex` (a female participant read as male), `ID` or a byte-order mark before `id` (the
    ids lost) and a BOM before `height` ("give height") are read as their columns."""
    from mjx_balance.model.subject import subject_rows

    rows = subject_rows(
        _csv(tmp_path, "ID, Height ,MASS,Sex,Ankle_Strength\nP1,1.6,55,Female,0.8\n")
    )
    assert [(r.line, r.id) for r in rows] == [(2, "P1")]
    assert rows[0].subject == Subject(1.6, 55, "female", 0.8)
    for header in ("id,height,mass,sex", "height,mass,sex"):  # the BOM before either column
        rows = subject_rows(
            _csv(
                tmp_path,
                f"{header}\n" + ("P1," if "id" in header else "") + "1.6,55,female\n",
                encoding="utf-8-sig",
            )
        )
        assert rows[0].subject == Subject(1.6, 55, "female")
        assert rows[0].id == ("P1" if "id" in header else "")


def test_csv_comment_and_blank_lines_are_skipped_and_lines_keep_their_numbers(tmp_path):
    """A `#` line before the header (it was read as the header: "give height") or between
    rows is a comment; errors still name the file's own line number."""
    from mjx_balance.model.subject import subject_rows

    path = _csv(
        tmp_path,
        "# participants of the pilot, 2024\nid,height,mass\n\n"
        "a,1.6,55\n  # b withdrew\nc,1.8,abc\n",
    )
    with pytest.raises(ParameterError, match=r"line 6: mass = 'abc'"):
        subject_rows(path)
    path.write_text("# pilot\nid,height,mass\na,1.6,55\n# b withdrew\nc,1.8,80\n")
    assert [(r.line, r.id) for r in subject_rows(path)] == [(3, "a"), (5, "c")]


@pytest.mark.parametrize(
    "header, words",
    [
        (
            "id,height,mass,ankle_strenght",
            [
                "unknown column(s) 'ankle_strenght'",
                "known columns: id, height, mass, sex, ankle_strength",
            ],
        ),
        ("id,height,mass,weight", ["'weight'"]),
        ("id;height;mass", ["'id;height;mass'", "separated by commas"]),
        ("id,height,Height,mass", ["column 'height' is given twice"]),
        ("id,mass", ["line 1: the header has no column height"]),
    ],
)
def test_csv_an_unknown_repeated_or_missing_column_is_refused_by_name(tmp_path, header, words):
    """A misspelt column was ignored (every strength stayed 1): any column that is not a
    subject's field, the id or a free-text note is refused, naming it and the known ones."""
    from mjx_balance.model.subject import subjects_from_csv

    path = _csv(tmp_path, f"{header}\n" + ",".join(["x"] * len(header.split(","))) + "\n")
    with pytest.raises(ParameterError) as err:
        subjects_from_csv(path)
    message = str(err.value)
    assert message.startswith(str(path)) and "\n" not in message
    for word in words:
        assert word in message


def test_csv_notes_columns_are_read_and_ignored(tmp_path):
    from mjx_balance.model.subject import subjects_from_csv

    path = _csv(tmp_path, 'id,height,mass,Notes\na,1.6,55,"tall, left-handed"\n')
    assert subjects_from_csv(path) == [Subject(1.6, 55)]


@pytest.mark.parametrize(
    "text, words",
    [
        (
            "id,height,mass\nP1,1,6,55\n",
            ["line 2: 4 values for the header's 3 columns", "decimal comma"],
        ),
        (
            'id,height,mass\nP1,"1,6",55\n',
            ["line 2: height = '1,6' is not a number", "decimal comma"],
        ),
        ("id,height,mass,sex\nP1,1,6,55\n", ["line 2", "subject.sex = '55'"]),
        ("id,height,mass,,\nP1,1.6,55,,x\n", ["line 2: 'x' is in a column without a name"]),
        ("id,height,mass\n", ["holds a header and no subject"]),
        ("", ["empty"]),
    ],
)
def test_csv_a_decimal_comma_or_a_ragged_row_is_refused(tmp_path, text, words):
    """`P1,1,6,55` (height 1,6 m with a decimal comma) was read as a 1-m, 6-kg subject (the
    55 dropped): a row with more values than columns is refused naming its line."""
    from mjx_balance.model.subject import subjects_from_csv

    with pytest.raises(ParameterError) as err:
        subjects_from_csv(_csv(tmp_path, text))
    for word in words:
        assert word in str(err.value)


@pytest.mark.parametrize("height, mass", [(1.0, 6.0), (1.0, 75.0), (2.4, 50.0), (1.5, 140.0)])
def test_a_body_no_one_has_is_refused_on_every_path(tmp_path, height, mass):
    """Height and mass each in range can still make no body (1 m and 6 kg: the decimal
    comma's `1,6`): the body mass index is bounded (subject.BMI_RANGE), in the Subject's own
    check, so --subject, a [subject] table, a CSV row and mb.Subject refuse it alike."""
    from mjx_balance.model.subject import BMI_RANGE, subjects_from_csv

    bmi = mass / height**2
    assert not BMI_RANGE[0] <= bmi <= BMI_RANGE[1]
    for make in (
        lambda: Subject(height, mass),
        lambda: parse_subject(f"height={height},mass={mass}"),
        lambda: with_sections(Config(), {"subject": {"height": height, "mass": mass}}),
        lambda: subjects_from_csv(_csv(tmp_path, f"height,mass\n{height},{mass}\n")),
    ):
        with pytest.raises(ParameterError, match=r"body mass index .* outside the plausible"):
            make()
    # the bounds' own edges are bodies
    for bmi in BMI_RANGE:
        assert Subject(1.7, bmi * 1.7**2).mass == pytest.approx(bmi * 2.89)


def test_a_populations_bodies_lie_within_the_bounds():
    """A population draws height and mass independently: the mass is redrawn into the body
    mass indices a subject accepts at that height (no subject refused mid-draw)."""
    from mjx_balance.model.subject import BMI_RANGE
    from mjx_balance.studies import members as cohort_members

    tall_light = cohort_members.population(
        40, seed=2, height_mean=2.3, height_sd=0.1, mass_mean=45, mass_sd=10
    )
    bmi = np.array([m.subject.mass / m.subject.height**2 for m in tall_light])
    assert bmi.min() >= BMI_RANGE[0] and bmi.max() <= BMI_RANGE[1]
    # a seed's subjects are those it drew before the bound (none of them was outside it):
    # the first three of population(30, seed=7), as the code before the bound drew them
    assert [m.subject for m in cohort_members.population(30, seed=7)[:3]] == [
        Subject(1.7269, 66.71, "male"),
        Subject(1.6591, 58.1, "female"),
        Subject(1.8206, 64.09, "female"),
    ]
