"""The peak power law family: the law, its batched cross-validation and folds, its domain and model-file section.

Beneath it lie the model layer's shared modules (peak reading, folds, intervals, the file envelope); never PLS.
"""
