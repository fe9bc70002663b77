"""The paper's Tables 1-6 and perceived roughness as CSV (read by ``roughsense.paper``).

Transcribed from Yanwari & Okamoto, Sensors 25:2598 (2025); no code.
"""
