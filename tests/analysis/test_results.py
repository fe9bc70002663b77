"""The study's records (analysis/results.py): each stage of analyse_study returns its own frozen record, and
StudyResults is all of them at once, assembled after the last stage with no field waiting for a later one."""
from __future__ import annotations

import dataclasses

import pandas as pd
import pytest

from roughsense import paper
from roughsense.analysis import results as records
from roughsense.analysis.results import (
    Controls,
    CrossValidation,
    PaperComparisons,
    RunSettings,
    StricterSchemes,
    StudyFacts,
    StudyResults,
    UnseenSurfaces,
    paper_comparability,
)

STAGES = (StudyFacts, RunSettings, CrossValidation, Controls, StricterSchemes, PaperComparisons, UnseenSurfaces)


def _stage(cls):
    """A record of ``cls`` whose every field holds its own marker object, so identity says where a value came from."""
    return cls(**{f.name: object() for f in dataclasses.fields(cls)})


@pytest.mark.parametrize("cls", [*STAGES, StudyResults], ids=lambda c: c.__name__)
def test_every_stage_record_is_frozen(cls):
    record = _stage(cls)
    field = dataclasses.fields(cls)[0].name
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(record, field, None)


def test_no_field_of_the_results_has_a_default_waiting_for_a_later_stage():
    defaulted = [f.name for f in dataclasses.fields(StudyResults)
                 if f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING]
    assert defaulted == []
    with pytest.raises(TypeError):
        StudyResults(models=("pls",), fits=())  # a half-built record cannot be made


def test_the_results_are_the_stages_fields_each_from_one_stage():
    names = [f.name for cls in STAGES for f in dataclasses.fields(cls)]
    assert len(names) == len(set(names))  # no field is computed by two stages
    assert sorted(names) == sorted(f.name for f in dataclasses.fields(StudyResults))


def test_assemble_takes_each_field_from_the_stage_that_computed_it():
    stages = [_stage(cls) for cls in STAGES]
    assembled = StudyResults.assemble(*stages)
    for stage in stages:
        for field in dataclasses.fields(stage):
            assert getattr(assembled, field.name) is getattr(stage, field.name), field.name


def test_a_run_without_the_stricter_schemes_holds_empty_tables():
    skipped = StricterSchemes.skipped()
    assert skipped.held_out.empty and skipped.presses.empty and skipped.presses_needed == {}


def test_the_paper_values_describe_only_the_papers_design():
    specimens, conditions = list(paper.PAPER_SPECIMENS), list(paper.PAPER_CONDITIONS)
    pads, note = paper_comparability(specimens, [*paper.PAPER_PADS, "ridged"], conditions, paper.REFERENCE_SPECIMEN)
    assert pads == tuple(paper.PAPER_PADS) and "ridged" in note
    assert paper_comparability(specimens, list(paper.PAPER_PADS), conditions, paper.REFERENCE_SPECIMEN) == (
        tuple(paper.PAPER_PADS), "")
    pads, note = paper_comparability(specimens[:-1], list(paper.PAPER_PADS), conditions[:1], "R2")
    assert pads == () and note.count(";") == 2  # specimens, conditions and the reference: three reasons


def test_the_fit_views_arrange_what_the_fits_hold():
    """An empty fit stage says which fits exist when one is asked for that does not."""
    empty = CrossValidation(models=("pls",), fits=())
    assert empty.ordered_fits() == [] and empty.pads == []
    with pytest.raises(KeyError, match="fitted: none"):
        empty.condition_fit("smooth", "combined")
    assert list(empty.cv_table().columns) == ["pad", "condition", "cv", "n_components", "rmse", "model"]
    assert isinstance(empty.chosen_components(), pd.DataFrame)
    assert records.RESULT_COLUMNS[-1] == "model"
