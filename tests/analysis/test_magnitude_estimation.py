"""Magnitude-estimation data: validation, aggregation (median over sessions, geometric mean over
participants) and the presentation protocol."""
from __future__ import annotations

import itertools
import warnings
from html.parser import HTMLParser

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy import stats

from roughsense.analysis.magnitude_estimation import MissingRatingsWarning, aggregate_ratings, make_schedule
from roughsense.errors import ConfigError, InputError, RoughsenseWarning
from roughsense.io.ratings_file import natural_key, read_ratings, validate_ratings
from roughsense.paper import PAPER_SPECIMENS
from roughsense.report.ratings_sheet import render_sheet


def ratings_frame(table: dict[tuple[str, str], list[float]]) -> pd.DataFrame:
    """{(participant, specimen): [session 1, session 2, ...]} -> long ratings frame."""
    rows = [(p, str(k + 1), s, r) for (p, s), values in table.items() for k, r in enumerate(values)]
    return pd.DataFrame(rows, columns=["participant", "session", "specimen", "rating"])


def test_median_over_sessions_then_geometric_mean_over_participants():
    frame = ratings_frame({
        ("P1", "C2"): [1.0, 2.0, 4.0],  # median 2
        ("P2", "C2"): [0.5, 0.5, 8.0],  # median 0.5 (an outlier session does not matter)
        ("P3", "C2"): [1.0, 1.0, 1.0],  # median 1
        ("P1", "R5"): [1.0, 1.0, 1.0],
        ("P2", "R5"): [3.0, 3.0, 3.0],
        ("P3", "R5"): [2.0, 2.0, 2.0],
    })
    summary = aggregate_ratings(frame, "R3").set_index("specimen")
    assert list(summary.index) == ["C2", "R3", "R5"]
    assert summary.loc["C2", "gmean"] == pytest.approx(1.0)  # (2 * 0.5 * 1) ** (1/3)
    assert summary.loc["C2", "sd"] == pytest.approx(np.std([2.0, 0.5, 1.0], ddof=1))
    assert summary.loc["R5", "gmean"] == pytest.approx(6 ** (1 / 3))
    assert summary.loc["R5", "sd"] == pytest.approx(1.0)  # sample SD of 1, 2, 3
    assert (summary.loc["C2", "n_participants"], summary.loc["C2", "n_sessions"]) == (3, 3)
    ref = summary.loc["R3"]
    assert ref["gmean"] == 1.0 and np.isnan(ref["sd"]) and ref["n_participants"] == 0


positive = st.floats(0.05, 20, allow_nan=False)


@given(st.lists(st.lists(positive, min_size=3, max_size=3), min_size=2, max_size=6),
       st.floats(0.1, 10), st.randoms(use_true_random=False))
def test_ratio_scale_and_row_order_invariance(per_participant, factor, random):
    frame = ratings_frame({(f"P{i}", "R2"): values for i, values in enumerate(per_participant)})
    base = aggregate_ratings(frame).set_index("specimen").loc["R2"]
    medians = np.median(np.array(per_participant), axis=1)
    assert base["gmean"] == pytest.approx(stats.gmean(medians), rel=1e-12)
    # magnitude estimates are a ratio scale: a participant using bigger numbers scales both statistics
    scaled = frame.assign(rating=frame.rating * factor)
    again = aggregate_ratings(scaled).set_index("specimen").loc["R2"]
    assert again["gmean"] == pytest.approx(factor * base["gmean"], rel=1e-9)
    assert again["sd"] == pytest.approx(factor * base["sd"], rel=1e-9)
    order = list(frame.index)
    random.shuffle(order)
    shuffled = aggregate_ratings(frame.loc[order]).set_index("specimen").loc["R2"]
    assert shuffled["gmean"] == pytest.approx(base["gmean"], rel=1e-12)


def test_missing_session_warns_naming_the_gap_and_uses_the_remaining_sessions():
    frame = ratings_frame({
        ("P1", "C2"): [1.0, 2.0, 4.0], ("P1", "R2"): [0.5, 0.6, 0.7],
        ("P2", "C2"): [2.0, 2.0, 2.0], ("P2", "R2"): [0.4, 0.4, 0.4],
    })
    gappy = frame[~((frame.participant == "P1") & (frame.session == "2"))]
    gappy = gappy[~((gappy.participant == "P2") & (gappy.session == "3") & (gappy.specimen == "R2"))]
    with pytest.warns(MissingRatingsWarning) as record:
        summary = aggregate_ratings(gappy).set_index("specimen")
    messages = [str(w.message) for w in record]
    assert any("P1" in m and "session 2" in m and "no ratings" in m for m in messages)
    assert any("P2" in m and "session 3" in m and "R2" in m for m in messages)
    assert len(messages) == 2 and issubclass(MissingRatingsWarning, RoughsenseWarning)
    # P1's C2 median over sessions 1 and 3 is (1 + 4) / 2
    assert summary.loc["C2", "gmean"] == pytest.approx(np.sqrt(2.5 * 2.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        aggregate_ratings(gappy, warn=False)
        aggregate_ratings(frame)  # complete data: no warning at all


def test_specimen_list_orders_rows_and_every_listed_specimen_must_be_rated():
    frame = ratings_frame({("P1", "C2"): [1.0], ("P1", "R2"): [0.5], ("P2", "C2"): [1.2], ("P2", "R2"): [0.4]})
    summary = aggregate_ratings(frame, specimens=["R2", "R3", "C2"])
    assert list(summary.specimen) == ["R2", "R3", "C2"]
    with pytest.raises(InputError, match="no ratings at all for specimen.*R4"):
        aggregate_ratings(frame, specimens=["R2", "R3", "R4", "C2"])


def write(tmp_path, text, name="ratings.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


GOOD = "participant,session,specimen,rating\nP1,1,R2,0.5\nP1,1,C2,1.5\nP2,1,R2,0.4\nP2,1,C2,1.1\n"


@pytest.mark.parametrize(
    "text, row, column, message",
    [
        (GOOD + "P3,1,R2,0\n", 6, "rating", "positive"),
        (GOOD + "P3,1,R2,-1.5\n", 6, "rating", "positive"),
        (GOOD + "P3,1,R2,abc\n", 6, "rating", "not a number"),
        (GOOD + "P3,1,R2,inf\n", 6, "rating", "not a finite number"),
        (GOOD + "P3,1,R3,1.0\n", 6, "specimen", "reference"),
        (GOOD + "P2,1,R2,0.45\n", 6, "specimen", "twice.*line 4"),
        (GOOD + ",1,R2,0.45\n", 6, "participant", "empty"),
    ],
)
def test_bad_rows_are_errors_naming_the_line(tmp_path, text, row, column, message):
    with pytest.raises(InputError, match=message) as info:
        read_ratings(write(tmp_path, text))
    assert (info.value.row, info.value.column) == (row, column)


def test_missing_column_and_unknown_specimen(tmp_path):
    with pytest.raises(InputError, match="missing column.*rating"):
        read_ratings(write(tmp_path, "participant,session,specimen\nP1,1,R2\n"))
    with pytest.raises(InputError, match="unknown specimen 'C2'") as info:
        read_ratings(write(tmp_path, GOOD), specimens=["R2", "R3"])
    assert info.value.row == 3
    with pytest.raises(InputError, match="every rating cell is empty"):
        read_ratings(write(tmp_path, "participant,session,specimen,rating\nP1,1,R2,\n"))


def trailing_commas(text: str, *, header: bool) -> str:
    lines = text.splitlines()
    return "\n".join([lines[0] + ("," if header else ""), *(line + "," for line in lines[1:])]) + "\n"


def test_a_trailing_comma_on_every_line_is_read_as_without(tmp_path):
    plain = aggregate_ratings(read_ratings(write(tmp_path, GOOD)))
    frame = read_ratings(write(tmp_path, trailing_commas(GOOD, header=True), "commas.csv"))
    assert list(frame.columns) == ["participant", "session", "specimen", "rating"]
    summary = aggregate_ratings(frame)
    pd.testing.assert_frame_equal(summary, plain)
    gmean = summary.set_index("specimen")["gmean"]
    assert gmean["R2"] == pytest.approx(np.sqrt(0.5 * 0.4), rel=1e-12)
    assert gmean["C2"] == pytest.approx(np.sqrt(1.5 * 1.1), rel=1e-12)


@pytest.mark.parametrize(
    "text, row, value",
    [
        ("participant,session,specimen,rating\nP1,1,R2,0.5,9\nP2,1,R2,0.4,9\n", 2, "9"),  # pandas' index shift
        (GOOD + "P3,1,R2,0.7,,x\n", 6, "x"),  # extra empty fields are fine, a value after them is not
        (trailing_commas(GOOD, header=True) + "P3,1,R2,0.7,2\n", 6, "2"),  # a nameless column holds no data
    ],
)
def test_a_row_with_an_extra_value_names_its_line(tmp_path, text, row, value):
    with pytest.raises(InputError, match=f"header has 4 \\(extra value '{value}'\\)") as info:
        read_ratings(write(tmp_path, text))
    assert info.value.row == row and info.value.column is None


def test_a_row_wider_than_the_header_by_an_empty_field_is_refused(tmp_path):
    """Issue 28.3: blanks count; a trailing comma on the data rows but not the header is one too many fields."""
    with pytest.raises(InputError, match=r"5 fields but the header has 4 \(extra empty field\)") as info:
        read_ratings(write(tmp_path, trailing_commas(GOOD, header=False)))
    assert info.value.row == 2
    with pytest.raises(InputError, match="3 fields but the header has 4; write one field per column") as info:
        read_ratings(write(tmp_path, GOOD + "P3,1,R2\n"))
    assert info.value.row == 6


@pytest.mark.parametrize("cell", ["inf", "-Infinity", "nan", "1e999"])
def test_not_a_number_quotes_the_cell_as_written(tmp_path, cell):
    with pytest.raises(InputError) as info:
        read_ratings(write(tmp_path, GOOD + f"P3,1,R2,{cell}\n"))
    assert info.value.message == f"not a finite number: '{cell}'" and info.value.row == 6


def test_not_a_number_in_memory_is_formatted_not_numpy_repr():
    frame = ratings_frame({("P1", "R2"): [0.5, np.inf]})
    with pytest.raises(InputError) as info:
        validate_ratings(frame)
    assert info.value.message == "not a finite number: inf" and info.value.row == 3


def test_blank_rating_cells_are_trials_not_done(tmp_path):
    frame = read_ratings(write(tmp_path, GOOD + "P3,1,R2,\nP3,1,C2,2.0\n"))
    assert len(frame) == 5 and frame.index[-1] + 2 == 7  # rows keep their file line
    with pytest.warns(MissingRatingsWarning, match="P3, session 1: no rating for R2"):
        aggregate_ratings(frame)


def test_in_memory_frames_pass_the_readers_validator():
    """One validator: a frame built in memory gets the same checks and messages as a file."""
    frame = ratings_frame({("P1", "R2"): [0.5, -0.1]})
    with pytest.raises(InputError, match="positive") as info:
        validate_ratings(frame, path="study/ratings.csv")
    assert info.value.row == 3 and "study/ratings.csv" in str(info.value)


def test_a_study_folder_and_the_ratings_command_refuse_a_bad_rating_alike(tmp_path):
    """study.toml folders read ratings.csv through the same validator as `roughsense ratings`."""
    from roughsense.io.ratings_file import read_ratings_table

    path = write(tmp_path, GOOD + "P3,1,R2,0\n")
    with pytest.raises(InputError) as by_study:
        read_ratings_table(path)
    with pytest.raises(InputError) as by_command:
        read_ratings(path)
    assert str(by_study.value) == str(by_command.value)
    assert by_study.value.message == "a magnitude estimate must be positive, got 0" and by_study.value.row == 6


# --------------------------------------------------------------------------- protocol


def test_schedule_presents_every_specimen_once_per_session_and_never_the_reference():
    schedule = make_schedule(PAPER_SPECIMENS, 10, 3, "R3", rng=np.random.default_rng(7))
    assert list(schedule.columns) == ["participant", "session", "order", "specimen", "rating"]
    assert len(schedule) == 10 * 3 * 13 and schedule["rating"].isna().all()
    assert "R3" not in set(schedule.specimen)
    for _, block in schedule.groupby(["participant", "session"]):
        assert sorted(block.specimen) == sorted(s for s in PAPER_SPECIMENS if s != "R3")
        assert list(block.order) == list(range(1, 14))
    orders = {key: tuple(block.specimen) for key, block in schedule.groupby(["participant", "session"])}
    assert len(set(orders.values())) == 30  # redrawn for every participant and session
    again = make_schedule(PAPER_SPECIMENS, 10, 3, "R3", rng=np.random.default_rng(7))
    pd.testing.assert_frame_equal(schedule, again)
    other = make_schedule(PAPER_SPECIMENS, 10, 3, "R3", rng=np.random.default_rng(8))
    assert not schedule.specimen.equals(other.specimen)


def test_orders_are_uniform_over_positions():
    # 3000 sessions of 4 specimens: each specimen should land in each position a quarter of the time.
    schedule = make_schedule(["A", "B", "C", "D", "R3"], 1000, 3, rng=12345)
    counts = pd.crosstab(schedule.specimen, schedule.order).to_numpy()
    assert stats.chi2_contingency(counts).pvalue > 1e-3
    first = schedule[schedule.order == 1].specimen.value_counts().to_numpy()
    assert stats.chisquare(first).pvalue > 1e-3


def test_schedule_refuses_bad_designs():
    with pytest.raises(ConfigError, match="rng"):
        make_schedule(["R2", "C2"], 2, 1)  # an unseeded schedule could never be reproduced
    with pytest.raises(ConfigError, match="twice"):
        make_schedule(["R2", "R2"], 2, 1, rng=0)
    with pytest.raises(ConfigError, match="besides the reference"):
        make_schedule(["R3"], 2, 1, rng=0)
    with pytest.raises(ConfigError):
        make_schedule(["R2"], 0, 1, rng=0)
    with pytest.raises(ConfigError):
        make_schedule(["R2"], ["ann", "ann"], 1, rng=0)


class _Cells(HTMLParser):
    def __init__(self):
        super().__init__()
        self.rows, self._row, self._cell = [], None, None

    def handle_starttag(self, tag, attrs):
        if tag == "tr":
            self._row = []
        elif tag in ("td", "th") and self._row is not None:
            self._cell = ""

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._row is not None:
            self._row.append(self._cell.strip())
            self._cell = None
        elif tag == "tr":
            self.rows.append(self._row)
            self._row = None


def test_html_sheet_mirrors_the_schedule_with_blank_rating_cells():
    schedule = make_schedule(["R2", "C2", "C<5>"], ["P1", "P2"], 2, rng=3)
    page = render_sheet(schedule, "html")
    parser = _Cells()
    parser.feed(page)
    body = [r for r in parser.rows if r[0] != "line"]
    assert len(body) == len(schedule)
    for k, (row, expected) in enumerate(zip(body, schedule.itertuples())):
        assert row == [str(k + 2), str(expected.order), expected.specimen, ""]  # CSV line, order, specimen, blank
    assert page.count("<section>") == 4 and "C&lt;5&gt;" in page


def test_filled_markdown_sheet_reads_back_as_the_ratings(tmp_path):
    schedule = make_schedule(["R2", "R3", "C2", "C3"], 3, 2, rng=11)
    sheet = render_sheet(schedule, "markdown").splitlines()
    rng = np.random.default_rng(0)
    filled, expected = [], []
    for line in sheet:
        if line.startswith("| P"):
            value = round(float(rng.uniform(0.2, 3)), 2)
            line = line.replace("|  |", f"| {value} |")
            cells = [c.strip() for c in line.strip("|").split("|")]
            expected.append((cells[0], cells[1], cells[3], value))
        filled.append(line)
    path = tmp_path / "sheet.md"
    path.write_text("\n".join(filled))
    got = read_ratings(path)
    assert list(zip(got.participant, got.session, got.specimen, got.rating)) == expected
    truth = pd.DataFrame(expected, columns=["participant", "session", "specimen", "rating"])
    pd.testing.assert_frame_equal(aggregate_ratings(got), aggregate_ratings(truth))
    # errors name the line of the Markdown file
    bad = filled.copy()
    k = next(i for i, line in enumerate(bad) if line.startswith("| P"))
    bad[k] = bad[k].rsplit("|", 2)[0] + "| -1 |"
    path.write_text("\n".join(bad))
    with pytest.raises(InputError) as info:
        read_ratings(path)
    assert info.value.row == k + 1 and info.value.column == "rating"


def test_natural_order_of_names():
    names = ["R10", "C2.5", "R2", "C2", "R2.5", "P10", "P9"]
    assert sorted(names, key=natural_key) == ["C2", "C2.5", "P9", "P10", "R2", "R2.5", "R10"]
    assert list(itertools.islice(PAPER_SPECIMENS, 3)) == ["R2", "R2.5", "R3"]
