"""The spatial-coding sensor: a contact image becomes a normalised amplitude spectrum (the model's X).

Crop, gray, a line across the contact, Fourier amplitudes on a fixed grid, normalised; the settings come from io/.
"""
