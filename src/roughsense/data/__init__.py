"""Package data shipped with roughsense: the paper's published tables and the sample images.

No code: the files are read with importlib.resources, so an installed package finds them offline.
"""
