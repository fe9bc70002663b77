"""The simulator writes a valid study folder, reproducibly, with the paper's design and physics."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from roughsense.errors import ConfigError, OutputExistsError
from roughsense.io.study import COMPLETE_MARKER, read_study
from roughsense.sim import SimulationConfig, SimulationRun, simulate_study
from roughsense.sim.bench import BenchNoise
from roughsense.sim.optics import Camera

SMALL = Camera(width_px=400, height_px=300)


def _config(**kw) -> SimulationConfig:
    base = dict(pads=("smooth", "fingerprint"), specimens=("R2", "C3"), forces_n=(1.0, 2.0), repetitions=1,
                seed=3, camera=SMALL)
    base.update(kw)
    return SimulationConfig(**base)


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_default_config_is_the_papers_full_study():
    config = SimulationConfig()
    run_size = len(config.pads) * len(config.specimens) * len(config.forces_n) * config.repetitions
    assert run_size == 840
    assert (config.participants, config.sessions, len(config.specimens) - 1) == (10, 3, 13)
    assert config.camera == Camera() and (config.camera.width_px, config.camera.height_px) == (1920, 1080)


def test_study_folder_follows_the_contract(tmp_path):
    seen = {}

    def progress(items, *, total, description):
        seen["total"] = total
        for i, item in enumerate(items, start=1):
            seen["done"] = i
            yield item

    out = simulate_study(tmp_path / "s", _config(), jobs=1, progress=progress)
    assert seen == {"total": 8, "done": 8}
    assert (out / COMPLETE_MARKER).is_file()
    study = read_study(out, require_ratings=True)
    assert study.reference_specimen == "R3" and study.sensor.px_per_mm == 34.9 and study.sensor.roi == "center"
    assert study.forces_n == (1.0, 2.0)
    assert study.extra["simulation"]["seed"] == 3
    assert list(study.specimens["specimen"]) == ["R2", "C3"]
    assert set(study.specimens["ratings_source"]) == {"paper"}
    r2 = study.specimens.set_index("specimen").loc["R2"]
    assert (r2["shape"], r2["wavelength_mm"], r2["groove_depth_mm"], r2["ridge_width_mm"]) == ("rectangular", 2, 1, 1)
    assert study.specimens.set_index("specimen").loc["C3", "diameter_mm"] == 3.0
    m = study.manifest
    assert len(m) == 2 * 2 * 2 * 1
    assert set(m.columns) >= {"image", "specimen", "pad", "force_n", "nominal_force_n", "repetition", "contact_fraction"}
    assert (np.abs(m["force_n"] - m["nominal_force_n"]) < 0.3).all()
    assert ((m["contact_fraction"] > 0) & (m["contact_fraction"] < 1)).all()
    assert len(study.ratings) == 10 * 3 * 2
    import cv2
    image = cv2.imread(str(out / m["image"][0]), cv2.IMREAD_UNCHANGED)
    assert image.shape == (300, 400) and image.dtype == np.uint8
    band = image[140:160].mean()
    assert band > 2 * image[:20].mean()  # the contact band sits in the middle of the frame


def test_same_seed_gives_identical_files_whatever_the_jobs(tmp_path):
    a = simulate_study(tmp_path / "a", _config(), jobs=1)
    b = simulate_study(tmp_path / "b", _config(), jobs=2)
    assert _files(a) == _files(b)
    c = simulate_study(tmp_path / "c", _config(seed=4), jobs=1)
    assert _files(c)["images/smooth_R2_1N_r01.png"] != _files(a)["images/smooth_R2_1N_r01.png"]


def test_an_image_does_not_depend_on_the_other_specimens_in_the_run(tmp_path):
    full = simulate_study(tmp_path / "full", _config(), jobs=1)
    alone = simulate_study(tmp_path / "alone", _config(specimens=("C3",), pads=("fingerprint",)), jobs=1)
    name = "images/fingerprint_C3_2N_r01.png"
    assert (full / name).read_bytes() == (alone / name).read_bytes()


@pytest.mark.parametrize(("force_n", "shortfall"), [(1.0, 0.010), (3.0, 0.025)])
def test_ground_truth_contact_fraction_on_a_quiet_bench(tmp_path, force_n, shortfall):
    quiet = BenchNoise().scaled(0.0)
    whole_periods = Camera(width_px=420, height_px=300, px_per_mm=35.0)  # a 12 mm field: six 2 mm periods
    config = _config(pads=("smooth",), specimens=("C2",), forces_n=(force_n,), bench=quiet, camera=whole_periods)
    study = read_study(simulate_study(tmp_path / "q", config, jobs=1))
    # the field lies inside the 50 mm specimen; periodic Hertz minus the neighbours' interaction (docs/simulator.md)
    p = force_n / 500e-6
    e_star = 0.17e6 / (1 - 0.49**2)
    hertz = 2 * math.sqrt(4 * p * 2.0 * 1.0 / (math.pi * e_star)) / 2.0
    assert study.manifest["contact_fraction"][0] == pytest.approx(hertz * (1 - shortfall), rel=0.02)
    assert study.manifest["force_n"][0] == pytest.approx(force_n, abs=0.005)  # only the scale's 1 g steps remain


def test_new_specimens_get_physics_ratings(tmp_path):
    config = _config(pads=("smooth",), specimens=("R3", "R2", "sin:3:0.3", "rand:1.5:0.2"), forces_n=(1.0,))
    study = read_study(simulate_study(tmp_path / "n", config, jobs=1))
    assert study.extra["simulation"]["ratings_from"] == "paper"
    sources = study.specimens.set_index("specimen")["ratings_source"]
    assert dict(sources) == {"R3": "paper", "R2": "paper", "sin_3_0.3": "physics", "rand_1.5_0.2": "physics"}
    assert set(study.ratings["specimen"]) == {"R2", "sin_3_0.3", "rand_1.5_0.2"}
    assert set(study.specimens["shape"]) == {"rectangular", "sinusoidal", "random"}
    # --ratings-from physics changes only the presets' ratings, never the images; same seed, same bytes
    physics = simulate_study(tmp_path / "p", dataclasses.replace(config, ratings_from="physics"), jobs=1)
    again = simulate_study(tmp_path / "q", dataclasses.replace(config, ratings_from="physics"), jobs=1)
    assert _files(physics) == _files(again)
    before, after = _files(tmp_path / "n"), _files(physics)
    assert {k for k in before if before[k] != after[k]} == {"ratings.csv", "specimens.csv", "study.toml"}
    ratings = read_study(physics).ratings
    for name in ("sin_3_0.3", "rand_1.5_0.2"):  # the physics specimens' ratings do not depend on the mode
        assert (ratings[ratings["specimen"] == name].sort_values(["participant", "session"])["rating"].tolist()
                == study.ratings[study.ratings["specimen"] == name]
                .sort_values(["participant", "session"])["rating"].tolist())
    with pytest.raises(ConfigError, match="ratings-from"):
        SimulationRun(tmp_path / "bad", dataclasses.replace(config, ratings_from="paper+physics"))
    assert not (tmp_path / "bad").exists()


def test_refuses_a_non_empty_folder_and_never_deletes(tmp_path):
    out = tmp_path / "s"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    for force in (False, True):  # --force replaces only an earlier simulation, never a folder of other files
        with pytest.raises(OutputExistsError, match="not empty"):
            SimulationRun(out, _config(), force=force)
        assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    sim = tmp_path / "sim"
    simulate_study(sim, _config(), jobs=1)
    (sim / "notes.txt").write_text("mine")
    with pytest.raises(OutputExistsError):
        SimulationRun(sim, _config())
    simulate_study(sim, _config(pads=("smooth",)), force=True, jobs=1)
    assert (sim / "notes.txt").read_text() == "mine"
    assert read_study(sim).manifest.shape[0] == 4


def test_force_never_writes_over_a_real_study(tmp_path):
    from roughsense.io.sensor_settings import SensorSettings
    from roughsense.io.writer import StudyWriter

    rig = StudyWriter(tmp_path / "rig")
    rig.write_config(name="bench", sensor=SensorSettings(px_per_mm=34.9), extra={"rig": {"camera": "C920"}})
    rig.write_image("smooth_R2_2N_r01.png", np.full((300, 400), 7, dtype=np.uint8))
    before = _files(rig.root)
    with pytest.raises(OutputExistsError, match="not a simulated study"):
        SimulationRun(rig.root, _config(pads=("smooth",), specimens=("R2",), forces_n=(2.0,)), force=True)
    assert _files(rig.root) == before
    # an interrupted simulation (only its empty images/ folder) may be re-run without --force... or with it
    stub = tmp_path / "stub"
    (stub / "images").mkdir(parents=True)
    SimulationRun(stub, _config(), force=True)


@pytest.mark.parametrize("forces", [(1.0, 1.0000001), (100.0001, 100.0002), (1e-7, 2e-7), (2.0, 2.0)])
def test_forces_that_would_share_an_image_or_a_seed_are_refused(tmp_path, forces):
    with pytest.raises(ConfigError, match="--forces"):
        SimulationRun(tmp_path / "x", _config(forces_n=forces))
    assert not (tmp_path / "x").exists()


def test_specimens_whose_images_would_collide_are_refused(tmp_path):
    with pytest.raises(ConfigError, match="same image"):
        SimulationRun(tmp_path / "x", _config(specimens=("rect:3", "Rect:3")))
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("change", [dict(fingerprint_period_mm=-1.0), dict(fingerprint_period_mm=0.0),
                                   dict(fingerprint_period_mm=math.nan), dict(ridge_height_mm=math.inf),
                                   dict(ridge_height_mm=0.0), dict(seed=-1), dict(sessions=0)])
def test_numeric_options_are_checked_even_when_no_pad_uses_them(tmp_path, change):
    with pytest.raises(ConfigError):
        SimulationRun(tmp_path / "x", _config(pads=("smooth",), **change))
    assert not (tmp_path / "x").exists()


def test_every_ridge_of_a_long_domain_gets_its_own_height_error():
    from roughsense.sim.bench import MAX_RIDGES, draw_mount
    from roughsense.sim.plan import plan_trials
    from roughsense.sim.trial_contact import ridges_in_domain

    config = _config(pads=("fingerprint",), specimens=("rand:1:0.1",), forces_n=(1.0,), fingerprint_period_mm=0.2)
    pads, specimens = config.validate()
    assert ridges_in_domain(pads[0], specimens[0]) == 250  # a 50 mm random grating under 0.2 mm ridges
    mount = plan_trials(config, pads, specimens)[0].mount
    offsets = np.asarray(mount.ridge_offsets_mm)
    assert offsets.size == 250 and np.unique(offsets).size == 250
    assert offsets.std() == pytest.approx(BenchNoise().ridge_height_sd_mm, rel=0.25)
    # the extra ridges are drawn last, so a domain with few ridges draws exactly as before
    short = draw_mount(np.random.default_rng(1), BenchNoise(), 1.0)
    long = draw_mount(np.random.default_rng(1), BenchNoise(), 1.0, ridges=300)
    assert long.ridge_offsets_mm[:MAX_RIDGES] == short.ridge_offsets_mm and len(long.ridge_offsets_mm) == 300
    assert dataclasses.replace(long, ridge_offsets_mm=short.ridge_offsets_mm) == short


@pytest.mark.parametrize("change", [dict(pads=("velvet",)), dict(specimens=("R9",)), dict(forces_n=(1.0, -2.0)),
                                   dict(specimens=("rect:0",)), dict(repetitions=0), dict(specimens=("R2", "R2"))])
def test_bad_options_fail_before_writing(tmp_path, change):
    with pytest.raises(ConfigError):
        SimulationRun(tmp_path / "x", dataclasses.replace(_config(), **change))
    assert not (tmp_path / "x").exists()


def test_simulate_study_is_a_public_name():
    import roughsense

    assert roughsense.simulate_study is simulate_study
