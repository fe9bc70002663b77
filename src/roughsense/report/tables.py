"""Report tables in the paper's layout: the names of paper_tables, control_tables and unseen_tables, re-exported
for one release (import them from those modules)."""
from __future__ import annotations

# re-exported for one release
from .control_tables import (  # noqa: F401
    _claim_p,
    _control_row,
    _of_model,
    _p_phrase,
    _verdict_text,
    claims_table,
    control_flags,
    control_text,
    controls_report_table,
    headline_table,
    permutation_p_text,
)
from .paper_tables import (  # noqa: F401
    CONDITION_TITLES,
    FLAG,
    GROUP_TITLES,
    OUT_OF_FOLD,
    _cell,
    _num,
    _paper_lookup,
    _pm,
    _quiet_nanmean,
    components_table,
    is_paper_model,
    metric_table,
    model_title,
    prediction_table,
    tests_table,
)
from .unseen_tables import (  # noqa: F401
    _coverage_text,
    _flag_text,
    _jackknife_text,
    held_out_table,
    jackknife_phrase,
    paper_predictive_table,
    unseen_table,
    unsure_table,
)
