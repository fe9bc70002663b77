"""The groove family: perceived roughness from the contact's geometry (land and groove widths per press), its terms
chosen by nested leave-one-specimen-out, its batched cross-validation, its land/groove domain and model-file section.

Beneath it lie the model layer's shared modules (folds, intervals, the file envelope); never PLS or the peak law.
"""
