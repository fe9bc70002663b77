"""The PLS family: SIMPLS, its exact cross-validation, its applicability domain and its model-file section.

Beneath it lie the model layer's shared modules (peak reading, folds, intervals, the file envelope); never the peak law.
"""
