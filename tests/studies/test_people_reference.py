"""The people reference (data/references/people.csv): published measurements of people's
balance recovery, as printed. The values are pinned here as the papers print them; each row's
mean (and SD, where given) must also appear in the sentence quoted from the paper, so a value
edited in the table without its source fails."""

import re
import pandas as pd

from mjx_balance.studies.references import read_people

# measure -> (mean, sd or None, unit), as printed in the abstracts (the file's read_in column)
PRINTED = {
    "lean_release_static_recovery_limit_young": (14.9, 1.4, "deg"),  # Robinovitch 2002
    "lean_release_max_angle_young": (5.9, 1.1, "deg"),
    "lean_release_peak_ankle_torque_young": (116, 32, "N m"),
    "lean_release_torque_onset_latency_young": (99, 13, "ms"),
    "lean_release_ankle_rtd_young": (372, 267, "N m/s"),
    "lean_release_single_step_max_angle_young_men": (32.5, None, "deg"),  # Thelen 1997
    "lean_release_single_step_max_angle_older_men": (23.9, None, "deg"),
    "lean_release_single_step_max_angle_young_women": (30.7, None, "deg"),  # Wojcik 1999
    "lean_release_single_step_max_angle_older_women": (16.2, None, "deg"),
    "waist_pull_step_threshold_older_fallers": (7.5, 1.4, "% total body weight"),  # DePasquale
    "waist_pull_step_threshold_older_nonfallers": (12.3, 1.7, "% total body weight"),
    "platform_translation_max_no_step_young": (16.2, 2.6, "cm"),  # Koushyar 2019
    "platform_translation_max_no_step_older": (11.8, 2.1, "cm"),
}


def people() -> pd.DataFrame:
    return read_people()


def test_the_people_reference_holds_the_printed_values():
    frame = people().set_index("measure")
    assert sorted(frame.index) == sorted(PRINTED)
    for measure, (mean, sd, unit) in PRINTED.items():
        row = frame.loc[measure]
        assert row["mean"] == mean and row["unit"] == unit, measure
        assert pd.isna(row["sd"]) if sd is None else row["sd"] == sd, measure


def test_each_value_is_in_the_quoted_sentence_with_its_source():
    for _, row in people().iterrows():
        numbers = {float(x) for x in re.findall(r"\d+(?:\.\d+)?", row["quote"])}
        assert row["mean"] in numbers, row["measure"]
        assert pd.isna(row["sd"]) or row["sd"] in numbers, row["measure"]
        assert re.search(r"\(\d{4}\)", row["source"]), row["measure"]  # authors (year), journal
        assert row["doi"].startswith("10."), row["measure"]
        assert row["read_in"] == "abstract" and row["population"] and row["n"], row["measure"]


def test_at_least_eight_measures_from_four_studies_young_and_older():
    frame = people()
    studies = {re.sub(r"\s*\(\d{4}\).*", "", s) for s in frame["source"]}
    assert len(frame) >= 8 and len(set(frame["doi"])) >= 4 and len(studies) >= 4
    assert frame["population"].str.contains("young").any()
    assert frame["population"].str.contains("older").any()
