"""analysis/assessment.py: a verdict on the unseen-surface controls names what was held out (a grating left out
of training), not "surfaces it never saw"."""
from __future__ import annotations

from roughsense.analysis.assessment import UnseenAssessment
from roughsense.model.interval import PredictionInterval


def test_a_failed_control_names_the_grating_left_out():
    interval = PredictionInterval(trial_log_halfwidth=0.5, surface_log_halfwidth=0.4)
    verdict = UnseenAssessment(rmse=0.36, null_rmse=0.35, pooled_rmse=0.40, null_pooled_rmse=0.38, permutation_p=0.12,
                               n_permutations=199, passes=False, interval=interval)
    assert verdict.failure == (
        "this model FAILS its controls for a grating left out of training (nested leave-one-specimen-out): no better "
        "than the training mean (pooled RMSE 0.400 vs 0.380); not better than shuffled targets (permutation p = 0.120 "
        ">= 0.05, 199 shufflings). Its predictions for new surfaces are no better than guessing")
