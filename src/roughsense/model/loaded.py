"""What a model read from a model file carries beside its fitted numbers, shared by every family's estimator.

``load_model`` returns the family's own fitted estimator (a :class:`~roughsense.model.pls.simpls.SIMPLS` or a
:class:`~roughsense.model.peak_law.law.PeakPowerLaw`), so a loaded model predicts with the very code that was fitted.
The file adds what the estimator cannot know (where its spectra come from, what it was trained on), kept in
``model_file_``; :class:`FromModelFile` gives both families, once, what that makes them answer: their force
conditions, the path that names them in errors, and a refusal naming the file for spectra of the wrong width.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ModelFileError


@dataclass(frozen=True)
class ModelFileInfo:
    """A model file's own part: its path (None in memory), feature definition (``{"spectrum": ..., "conditions":
    [...]}``), training record and the roughsense version that wrote it."""

    path: Path | None
    features: dict
    training: dict
    roughsense_version: str


class FromModelFile:
    """Mixed into each family's estimator: what a loaded model answers from its ``model_file_``.

    A freshly fitted estimator has no ``model_file_``; its inputs are then checked by scikit-learn alone.
    """

    @property
    def path(self) -> Path | None:
        return self.model_file_.path

    @property
    def training(self) -> dict:
        return self.model_file_.training

    @property
    def roughsense_version(self) -> str:
        return self.model_file_.roughsense_version

    @property
    def conditions(self) -> list[str]:
        """Force conditions, in the order a trial's images are concatenated (one for a single-force model)."""
        return list(self.model_file_.features["conditions"])

    @property
    def n_features(self) -> int:
        return int(self.n_features_in_)

    def _file_inputs(self, X):
        """``X`` as floats, refused in one line naming the model file when its width is not the model's (a loaded
        model only: a fresh fit leaves its inputs to scikit-learn's checks)."""
        if not hasattr(self, "model_file_"):
            return X
        X = np.asarray(X, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != self.n_features:
            raise ModelFileError(f"the model expects {self.n_features} features per sample, got shape {X.shape}",
                                 path=self.path)
        return X

    def extrapolates(self, X, surfaces=None) -> np.ndarray:
        """True for each row outside the model's applicability domain (``applicability`` gives the reasons).

        Parameters
        ----------
        X : array-like
            (n_samples, n_features) spectra.
        surfaces : array-like, optional
            (n_samples,) labels: rows of one surface are presses of it.

        Returns
        -------
        numpy.ndarray
            (n_samples,) booleans.
        """
        return np.array([bool(reason) for reason in self.applicability(X, surfaces)], dtype=bool)
