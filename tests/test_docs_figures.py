"""Figures quoted in README.md and docs/ that the code can change: each is checked here against the code's current
output or against BENCHMARKS.md (a generated record), so prose that drifts fails a test. Speed figures round down,
never up; a figure needing the full 840-image study is not quoted in prose but pointed to (the report, BENCHMARKS.md)."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


def _benchmark_row(start: str) -> str:
    rows = [line for line in (REPO / "BENCHMARKS.md").read_text(encoding="utf-8").splitlines() if line.startswith(start)]
    assert len(rows) == 1, f"BENCHMARKS.md has no single row starting {start!r}"
    return rows[0].split("|")[2]  # the result column


def _ratios(text: str) -> list[float]:
    return [float(x) for x in re.findall(r"(\d+(?:\.\d+)?)x", text)]


def test_the_readme_pls_speedups_are_at_most_the_recorded_ones():
    readme = " ".join((REPO / "README.md").read_text(encoding="utf-8").split())
    quoted = re.search(r"exact LOO over 1\.\.20 components is more than (\d+)× faster than scikit-learn and "
                       r"more than (\d+)× faster than ikpls", readme)
    assert quoted, "the README no longer quotes the LOO speed-ups; update this test with it"
    sklearn = _ratios(_benchmark_row("| LOO 1..20 components, n=140, p=135: >= 200x scikit-learn"))
    ikpls = _ratios(_benchmark_row("| same: >= 10x ikpls fast CV"))
    assert sklearn and ikpls
    assert float(quoted.group(1)) <= min(sklearn)
    assert float(quoted.group(2)) <= min(ikpls)


# --- figures the code produces, recomputed (each fast: no study is simulated) ---------------------------------------

DURATION = re.compile(r"\b\d+(?:\.\d+)?(?:\s?[-–]\s?\d+(?:\.\d+)?)?\s?(?:s|min|minutes?|seconds?)\b|half a minute|"
                      r"\bminutes\b")
FIRST_RUN = re.compile(r"first use|make study", re.IGNORECASE)  # a `make study` from an empty cache


def _prose(path: Path) -> str:
    return " ".join(path.read_text(encoding="utf-8").split())


def _quoted(text: str, pattern: str, where: str) -> list[str]:
    found = re.search(pattern, text)
    assert found, f"{where} no longer says {pattern!r}; update tests/test_docs_figures.py with it"
    return list(found.groups())


def _agrees(quoted: str, value: float) -> bool:
    """A figure quoted with d decimals agrees if the value rounds to it (half a unit of its last digit)."""
    decimals = len(quoted.split(".")[1]) if "." in quoted else 0
    return abs(value - float(quoted)) <= 0.5 * 10.0**-decimals + 1e-9


def test_the_first_run_time_is_stated_once_in_the_readme():
    """One measured first-run time (README, Quick start); the tutorial and the other docs point to it."""
    pages = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
    stated = []
    for page in pages:
        for sentence in re.split(r"(?<=[.!?])\s+(?=[A-Z`(])", _prose(page)):
            if FIRST_RUN.search(sentence) and DURATION.search(sentence):
                stated.append((page.name, sentence))
    assert len(stated) == 1 and stated[0][0] == "README.md", stated
    assert re.search(r"about \d+ s of the study's \d+ s on two free cores", stated[0][1]), stated


def test_the_readme_quotes_the_predictive_ovl_of_the_papers_own_predictions():
    from roughsense.analysis.spread import paper_predictive

    quoted = _quoted(_prose(REPO / "README.md"), r"it gives (\d\.\d+) \(fingerprint pad\) and (\d\.\d+) \(smooth "
                     r"pad\), against the paper's OVL of (\d\.\d+) and (\d\.\d+)", "README.md")
    table = paper_predictive()
    means = table[table["condition"] == "combined"].groupby("pad")[["ovl_predictive", "ovl"]].mean()
    computed = [means.loc["fingerprint", "ovl_predictive"], means.loc["smooth", "ovl_predictive"],
                means.loc["fingerprint", "ovl"], means.loc["smooth", "ovl"]]
    assert all(_agrees(q, v) for q, v in zip(quoted, computed)), (quoted, computed)


def test_the_readme_quotes_the_defaults_and_the_recorded_size():
    from roughsense import defaults

    readme = _prose(REPO / "README.md")
    (shufflings,) = _quoted(readme, r"(\d+) seeded shufflings by default", "README.md")
    assert int(shufflings) == defaults.PERMUTATIONS
    (pixels,) = _quoted(readme, r"max_pixels = (\d+)", "README.md")
    assert int(pixels) == defaults.MAX_PIXELS
    (gigabytes,) = _quoted(readme, r"840 images, about (\d\.\d) GB", "README.md")
    (megabytes,) = re.findall(r"(\d+) MB", _benchmark_row("| first run: simulated study on disk"))[:1]
    assert _agrees(gigabytes, float(megabytes) / 1000)


def test_the_rig_page_quotes_the_recorded_live_rate():
    low, high = _quoted(_prose(REPO / "docs" / "rig.md"), r"measures (\d+) to (\d+) updates/s", "docs/rig.md")
    recorded = re.search(r"(\d+)-(\d+) updates/s", _benchmark_row("| live scoring"))
    assert recorded and (int(low), int(high)) == (int(recorded.group(1)), int(recorded.group(2)))


def test_the_sensor_page_quotes_the_untapered_leakage():
    """docs/sensor.md: without a window a lateral shift moves the features by up to N % of the peak, over soft-edged
    gratings of 2-5 mm (the Hann window's < 1 % is tests/sensor/test_spectrum.py's, for any shift and period)."""
    from roughsense.sensor.line import spatial_spectrum

    (percent,) = _quoted(_prose(REPO / "docs" / "sensor.md"), r"by up to \*\*(\d+) % of the peak\*\*", "docs/sensor.md")

    def spectrum(wavelength_mm, shift_mm):
        x_mm = np.arange(1900) / 34.9 + shift_mm
        line = 0.2 + 0.5 * (0.5 + 0.5 * np.tanh(3.0 * np.sin(2 * np.pi * x_mm / wavelength_mm)))
        return spatial_spectrum(np.tile(line, (3, 1)), roi="0,0,1900,3", window="none")

    worst = 0.0
    for wavelength_mm in np.arange(2.0, 5.01, 0.25):
        reference = spectrum(wavelength_mm, 0.0)
        moved = max(np.abs(spectrum(wavelength_mm, s) - reference).max()
                    for s in np.linspace(0.0, wavelength_mm, 13)[1:-1])
        worst = max(worst, moved / reference.max())
    assert _agrees(percent, 100 * worst), worst


# --- docs/simulator.md, "The finger": every figure scripts/fit_finger_to_paper.py and the finger model produce -------------

def _finger_section() -> str:
    text = _prose(REPO / "docs" / "simulator.md")
    return text[text.index("## The finger"):text.index("## Reproducibility, speed, progress")]


@pytest.fixture(scope="module")
def finger_validation():
    from scripts.finger_fitting import geometric_leave_one_out, leave_one_out

    from roughsense.paper import PAPER_SPECIMENS, REFERENCE_SPECIMEN
    from roughsense.sim.panel import paper_perceived
    from roughsense.sim.specimens import PRESETS

    paper = paper_perceived()
    names = [n for n in PAPER_SPECIMENS if n != REFERENCE_SPECIMEN]
    specimens = [PRESETS[n] for n in names]
    gmean = paper.loc[names, "perceived_gmean"].to_numpy(float)
    sd = paper.loc[names, "perceived_sd"].to_numpy(float)
    human_log_sd = float(np.median(np.sqrt(np.log1p((sd / gmean) ** 2))))
    return leave_one_out(specimens, gmean), geometric_leave_one_out(specimens, gmean), human_log_sd


def test_the_finger_is_no_better_than_the_geometric_law_as_the_docs_say(finger_validation):
    from scripts.finger_fitting import DEPTHS_MM, SATURATIONS, paired_p

    finger, law, human_log_sd = finger_validation
    text = _finger_section()
    quoted = _quoted(text, r"the finger reaches Spearman ρ \*\*(\d\.\d+)\*\* and a median \|log error\| of "
                     r"\*\*(\d\.\d+)\*\*, the law ρ \*\*(\d\.\d+)\*\* and \*\*(\d\.\d+)\*\*; .*?Wilcoxon signed-rank "
                     r"p = \*\*(\d\.\d+)\*\*", "docs/simulator.md")
    computed = [finger.spearman, finger.median_abs_log_error, law.spearman, law.median_abs_log_error,
                paired_p(finger, law)]
    assert all(_agrees(q, v) for q, v in zip(quoted, computed)), (quoted, computed)
    table = _quoted(text, r"Spearman ρ of the held-out predictions \| \*\*(\d\.\d+)\*\* \| (\d\.\d+) \|.*?median "
                    r"\\\|log\(pred/obs\)\\\| \| \*\*(\d\.\d+)\*\* \| (\d\.\d+) \| < median human log-SD (\d\.\d+)",
                    "docs/simulator.md")
    assert all(_agrees(q, v) for q, v in zip(table, [*computed[:4][::2], *computed[1:4:2], human_log_sd])), table
    assert "in every leave-one-out fold" in text
    assert all(f.receptor_depth_mm == DEPTHS_MM[-1] and f.saturation_strain == SATURATIONS[0] for f in finger.folds)


def test_the_held_out_predictions_in_the_docs_are_the_codes(finger_validation):
    finger, law, _ = finger_validation
    text = _finger_section()
    (finger_list,) = _quoted(text, r"Held-out predictions \(paper → model\): (.*?)\. The model", "docs/simulator.md")
    pairs = re.findall(r"([RC][\d.]*\d) (\d\.\d+) → (\d\.\d+)", finger_list)
    assert [p[0] for p in pairs] == list(finger.names)
    for (_, observed, predicted), obs, pred in zip(pairs, finger.observed, finger.predicted):
        assert _agrees(observed, obs) and _agrees(predicted, pred), (observed, predicted, obs, pred)
    (law_list,) = _quoted(text, r"The geometric law's held-out predictions: (.*?)\.(?: |$)", "docs/simulator.md")
    law_pairs = re.findall(r"([RC][\d.]*\d) (\d\.\d+)", law_list)
    assert [p[0] for p in law_pairs] == list(law.names)
    assert all(_agrees(q, v) for (_, q), v in zip(law_pairs, law.predicted)), law_pairs


def test_the_finger_constants_and_examples_in_the_docs_are_the_codes():
    from roughsense.sim import finger, panel
    from roughsense.sim.specimens import parse_specimen

    text = _finger_section()
    (exponent,) = _quoted(text, r"\| exponent b \| \*\*(\d\.\d+) \(fitted\)\*\*", "docs/simulator.md")
    assert _agrees(exponent, finger.FITTED_EXPONENT)
    spreads = _quoted(text, r"scale_sd (\d\.\d+), exponent_sd (\d\.\d+), session_sd (\d\.\d+)", "docs/simulator.md")
    assert all(_agrees(q, v) for q, v in zip(spreads, (finger.FITTED_SCALE_SD, finger.FITTED_EXPONENT_SD,
                                                       finger.FITTED_SESSION_SD)))
    depth, saturation = _quoted(text, r"search bounds \((\d\.\d+) mm, (\d+) %\)", "docs/simulator.md")
    assert float(depth) == finger.FITTED_RECEPTOR_DEPTH_MM and float(saturation) / 100 == finger.FITTED_SATURATION_STRAIN
    spec = parse_specimen("sin:3:0.3")
    one, two = _quoted(text, r"finger\.magnitude\(spec\) # (\d\.\d+):.*?force_n=2\.0\) # (\d\.\d+):", "docs/simulator.md")
    assert _agrees(one, finger.magnitude(spec)) and _agrees(two, finger.magnitude(spec, force_n=2.0))
    g, s, lr = _quoted(text, r"Percept\(gmean=(\d\.\d+), sd=(\d\.\d+), source='physics', log_ratio=(\d\.\d+)\)",
                       "docs/simulator.md")
    percept = panel.percept(spec)
    assert _agrees(g, percept.gmean) and _agrees(s, percept.sd) and _agrees(lr, percept.log_ratio)


def _findings_row(first_cell: str) -> str:
    rows = [line for line in (REPO / "docs" / "simulator.md").read_text(encoding="utf-8").splitlines()
            if line.startswith(f"| {first_cell} |")]
    assert len(rows) == 1, f"docs/simulator.md has no single findings row {first_cell!r}"
    return rows[0]


def test_the_findings_table_quotes_the_models_values():
    from roughsense.sim.finger import magnitude
    from roughsense.sim.specimens import PRESETS, rectangular, sinusoidal

    def rect(groove, land):
        return magnitude(rectangular(groove + land, ridge_width_mm=land))

    groove = re.search(r"(\d\.\d+) → (\d\.\d+) \(1 mm lands\)", _findings_row("roughness rises with groove width at "
                                                                            "fixed land"))
    assert groove and _agrees(groove.group(1), rect(0.5, 1.0)) and _agrees(groove.group(2), rect(3.0, 1.0))
    land = _findings_row("falls with land width for narrow grooves")
    up = re.search(r"\*rises\* (\d\.\d+) → (\d\.\d+) \(0\.25 → 1\.25 mm\).*?falls (\d\.\d+) → (\d\.\d+) \(2 → 4 mm\)",
                   land)
    assert up and all(_agrees(q, v) for q, v in zip(up.groups(), (rect(1, 0.25), rect(1, 1.25), rect(1, 2), rect(1, 4))))
    half = re.search(r"\((\d\.\d+) at 0\.5 mm lands.*?falls (\d\.\d+) → (\d\.\d+) over 2 → 4 mm", land)
    assert half and all(_agrees(q, v) for q, v in zip(half.groups(), (rect(0.5, 0.5), rect(0.5, 2), rect(0.5, 4))))
    force = re.search(r"R3 (\d\.\d+) → (\d\.\d+)", _findings_row("rises with finger force"))
    assert force and _agrees(force.group(1), magnitude(PRESETS["R3"], force_n=0.25))
    assert _agrees(force.group(2), magnitude(PRESETS["R3"], force_n=3.0))
    amplitude = re.search(r"(\d\.\d+) → (\d\.\d+) \(λ = 3\)", _findings_row("rises with amplitude at a fixed wavelength"))
    assert amplitude and _agrees(amplitude.group(1), magnitude(sinusoidal(3.0, 0.02)))
    assert _agrees(amplitude.group(2), magnitude(sinusoidal(3.0, 1.0)))
    peak = re.search(r"peak (\d\.\d+) at 0\.35 mm⁻¹, (\d\.\d+) at 0\.45, (\d\.\d+) at 0\.8",
                     _findings_row("at a fixed groove width, falls again past a groove frequency of ~0.5 mm⁻¹"))
    assert peak and all(_agrees(q, rect(1.0, 1 / f - 1.0)) for q, f in zip(peak.groups(), (0.35, 0.45, 0.8)))
