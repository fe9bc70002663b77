"""Models from spectra to perceived roughness: SIMPLS, its exact fast cross-validation, model files, prediction.

A model family lives here beside SIMPLS and is chosen by name wherever SIMPLS is; model files are versioned JSON.
"""
