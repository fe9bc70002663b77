"""Where the cache lives: platformdirs' user cache folder after ``$ROUGHSENSE_CACHE_DIR``, on Linux the very folder the
hand-written rule gave (``$XDG_CACHE_HOME/roughsense``, else ``~/.cache/roughsense``), so no user's cache moves."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from roughsense._util import cache


def _old_rule(environ: dict[str, str]) -> Path:
    """The rule before platformdirs, written out here as the truth the new one must keep on Linux."""
    if environ.get("ROUGHSENSE_CACHE_DIR"):
        return Path(environ["ROUGHSENSE_CACHE_DIR"])
    base = environ.get("XDG_CACHE_HOME") or str(Path(environ["HOME"]) / ".cache")
    return Path(base) / "roughsense"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the old rule was Linux's (XDG)")
@pytest.mark.parametrize("explicit", [None, "", "/srv/rs-cache"])
@pytest.mark.parametrize("xdg", [None, "", "/var/tmp/xdg-cache"])
def test_the_cache_folder_is_where_it_was_on_linux(monkeypatch, tmp_path, explicit, xdg):
    environ = {"HOME": str(tmp_path / "home")}
    monkeypatch.setenv("HOME", environ["HOME"])
    for name, value in (("ROUGHSENSE_CACHE_DIR", explicit), ("XDG_CACHE_HOME", xdg)):
        if value is None:
            monkeypatch.delenv(name, raising=False)
        else:
            monkeypatch.setenv(name, value)
            environ[name] = value
    assert cache.cache_dir() == _old_rule(environ)
    assert cache.folder_entry("simulated-study", "v1") == _old_rule(environ) / "simulated-study-v1"
