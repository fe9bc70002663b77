"""Every sentence about where a study's data came from, and what that lets its numbers claim, in one place.

A simulated study's results are properties of the digital twin, a synthetic folder's illustrate the analysis, and
only a user's own images and ratings give findings about a real sensor; the console, the report's first screen, its
opening paragraphs, its "held out of training" section and its figure stamps all say so, and all in these words,
so no two of them can drift apart. The decision itself (:class:`roughsense.analysis.results.Provenance`) is made
once, when the study is analysed. The sentences for a report run without leave-one-specimen-out live here too: they
say what the data cannot answer.
"""
from __future__ import annotations

#: A simulated study's seed where its [simulation] table does not record one.
NOT_RECORDED = "not recorded"

#: What each renderer says when leave-one-specimen-out was not run: the console, the first screen, the section.
NO_LOSO_CONSOLE = ("Held-out surfaces: not estimated (--no-loso); the LOO lines below describe specimens seen in "
                   "training.")
NO_LOSO_ANSWER = ("Not answered: leave-one-specimen-out was not run (--no-loso), so this report cannot say how well any "
                  "model predicts a surface left out of training. The leave-one-out results below describe specimens "
                  "seen in training.")
NO_LOSO_SECTION = ("Leave-one-specimen-out was not run (--no-loso), so this report cannot say how well any model "
                   "predicts a grating left out of training; the LOO results below describe specimens seen in training.")

#: The words put before a figure's caption when its data are simulated.
STAMPED_CAPTION_PREFIX = "Simulated data. "


def _seed(provenance, missing: str = NOT_RECORDED):
    return missing if provenance.seed is None else provenance.seed


def source_label(provenance, *, builtin: bool) -> str:
    """The report's and the console's "source": simulated with its seed, synthetic with its note, or user data."""
    if provenance.kind == "synthetic":
        return f"synthetic images, not measurements: {provenance.note}"
    if provenance.kind == "user":
        return "user data (no [simulation] table in study.toml)"
    where = "built-in simulated study (digital twin)" if builtin else "simulated study (digital twin)"
    return f"simulated: {where}, simulation seed {_seed(provenance)}"


def simulated_banner(provenance) -> str | None:
    """The line under the page's title of a simulated study (None for any other)."""
    if provenance.kind != "simulated":
        return None
    return (f"Source: simulated (digital twin), simulation seed\n{_seed(provenance)}. Every image and rating below "
            "comes from the twin, not from a rig or people.")


def figure_stamp(provenance) -> str | None:
    """The text stamped across every figure of a simulated study (None for any other)."""
    return None if provenance.kind != "simulated" else f"SIMULATED DATA (seed {_seed(provenance, '?')})"


def trust_line(provenance) -> str:
    """The first screen's last sentence: how far to trust the numbers, from whose images and ratings these are."""
    if provenance.kind == "synthetic":
        return (f"How far to trust it: the images are synthetic ({provenance.note}), not measurements; the numbers "
                "illustrate the analysis, they are no finding about a real sensor.")
    if provenance.kind == "user":
        return ("How far to trust it: these are your images and ratings; the numbers are findings about them, for "
                "surfaces like the ones held out here.")
    return (f"How far to trust it: SIMULATED data (the digital twin, seed {_seed(provenance)}), not measurements. The "
            "numbers hold for the twin; a real rig confirms them only with real images and ratings of surfaces held "
            "out of training.")


def _synthetic_words(provenance) -> str:
    return (f"This study's images are synthetic, not measurements (study.toml [study] synthetic: {provenance.note}): "
            "the results illustrate the analysis and are no finding about a real sensor or real people.")


def source_paragraphs(provenance) -> list[str]:
    """The report's opening paragraphs on the source: what is a property of the simulator and what a finding."""
    if provenance.kind == "synthetic":
        return [_synthetic_words(provenance)]
    if provenance.kind == "user":
        return ["This study is user data (study.toml has no [simulation] table): every result below is a finding "
                "about these images and ratings."]
    if provenance.ratings_from == "paper":
        ratings = ("by default the simulated ratings of the paper's specimens are drawn from the paper's Table 1, so "
                   "perceived roughness, its spread and every claim about the ratings agree with the paper because "
                   "they were put in")
    else:
        ratings = (f"the ratings come from the simulator's finger model (ratings_from = {provenance.ratings_from}), so "
                   "every claim about the ratings is a property of that model, not of people")
    return [
        "This study is SIMULATED (study.toml has a [simulation] table; seed "
        f"{_seed(provenance)}). Properties of the simulator, not findings: {ratings}; "
        "and the simulator's noise was tuned so that leave-one-out errors land in the paper's range, so LOO RMSE "
        "and OVL close to the paper's confirm the tuning, not the method.",
        "Findings (about the digital twin, not about real skin or a real rig): whether the spectra predict roughness "
        "for a grating left out of training (LOSO; a period and a shape left out beside it), whether models beat "
        "specimen-shuffled targets and the training "
        "mean (Controls), and which of the paper's claims hold under those checks (Claims).",
    ]


def unseen_source_words(provenance) -> list[str]:
    """What the "held out of training" section can claim, given whose images and ratings these are."""
    if provenance.kind == "synthetic":
        return [_synthetic_words(provenance)]
    if provenance.kind == "user":
        return ["This is user data: the results are findings about these images and these ratings."]
    lines = ["The images are the digital twin's, not the paper's rig's: these results hold for the twin. To "
             "confirm them, a real rig needs real images and real people's ratings of surfaces held out of "
             "training (periods and shapes no training surface had), scored by a model fitted without them."]
    if provenance.ratings_from == "physics":
        lines.append("The ratings come from the simulated finger (ratings_from = physics), which reads the same "
                     "contact that the images show, so agreement between images and ratings is partly built in; "
                     "judge the models on the paper's ratings (ratings_from = paper).")
    return lines


#: What a sweep page says of its data: every cell is the twin's, and which of its agreement with the paper is tuned in.
SWEEP_LIMITS = [
    "The twin was calibrated to reproduce the paper's error regime with the paper's two pads (smooth; 1 mm fingerprint, "
    "0.2 mm ridges) on the paper's fourteen gratings. Agreement with the paper there is a property of the calibration, "
    "not a finding; every other design is an extrapolation of the same physics (elastic half-space contact, gap-to-"
    "brightness optics, bench noise drawn as in the calibration).",
    "With ratings_from = \"paper\", only the paper's fourteen presets carry the paper's panel; every other specimen "
    "gets its perceived roughness from the twin's simulated finger (sim/finger.py: contact of a fingertip, SA1 "
    "strain readout, a fitted power law), which ratings_from = \"physics\" uses for every specimen. Those targets are "
    "not measurements, so 'can it be measured' means 'does the sensor track the model'.",
    "The spectrum covers 0.1-1 mm^-1 (wavelengths 1-10 mm): a grating whose fundamental lies above 1 mm^-1 "
    "(wavelength below 1 mm) is seen only through its contact pattern's harmonics and aliasing of the pad relief.",
    "A shorter field is modelled as a narrower camera view of the same 50 x 10 mm contact; a physically smaller pad "
    "would also change the nominal pressure and the edge effects, which the twin does not model.",
    "The pad modulus enters only the contact mechanics (how far the pad sinks into the grooves); its optical and "
    "frictional consequences and its ageing are not modelled.",
]
