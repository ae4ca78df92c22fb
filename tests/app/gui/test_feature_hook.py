"""PySide6's import hook, made cheap (app/gui/feature_hook.py), answers as PySide6's own check."""

from __future__ import annotations

import sys

from ctdrill.app.gui import app, feature_hook


def test_the_window_installs_the_cheap_check_and_it_answers_as_pysides() -> None:
    assert app.feature_hook is feature_hook
    feature = sys.modules[feature_hook.FEATURE_MODULE]
    cheap = feature._mod_uses_pyside  # type: ignore[attr-defined]
    original = cheap.ctdrill_original
    assert not feature_hook.install()  # once
    modules = [m for m in list(sys.modules.values()) if hasattr(m, "__name__")]
    got = [cheap(m) for m in modules]
    assert got == [original(m) for m in modules]
    names = {m.__name__ for m, uses in zip(modules, got, strict=True) if uses}
    assert "ctdrill.app.gui.main_window" in names and "numpy" not in names
