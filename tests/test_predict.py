"""``model/predict.py`` heads the predict chain: each module of the chain imports only modules below it, so the
chain reads top-down (``rs.predict`` -> trials, scoring, the table -> the gate, the reasons, the intervals -> the
model's spectrum), and ``roughsense.predict`` is the call that lives in ``model/predict.py``."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

import roughsense

MODEL = Path(roughsense.__file__).parent / "model"
#: The chain's floors, top first: a module may import a chain module only from a lower floor.
FLOORS = [("predict",), ("trials", "scoring", "predict_table"), ("press_gate", "outside", "model_intervals"),
          ("reading",)]
FLOOR = {name: depth for depth, names in enumerate(FLOORS) for name in names}


def chain_imports(name: str) -> set[str]:
    """The chain modules ``model/<name>.py`` imports at run time (anywhere in it; type-checking imports aside)."""
    tree = ast.parse((MODEL / f"{name}.py").read_text(encoding="utf-8"))
    typing_only = {id(node) for block in ast.walk(tree) if isinstance(block, ast.If)
                   and ast.unparse(block.test) == "TYPE_CHECKING" for node in ast.walk(block)}
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and id(node) not in typing_only and node.level == 1 and node.module:
            found.add(node.module.split(".")[0])
    return found & set(FLOOR)


@pytest.mark.parametrize("name", sorted(FLOOR))
def test_each_module_of_the_chain_calls_only_down(name):
    upward = {other for other in chain_imports(name) if FLOOR[other] <= FLOOR[name]}
    assert not upward, f"model/{name}.py imports {sorted(upward)} from its own floor or above"


def test_the_public_predict_lives_in_the_module_named_for_it():
    from roughsense.model import predict

    assert roughsense.predict is predict.predict
    assert not hasattr(predict, "score_trials") and not hasattr(predict, "SensorOverride")
