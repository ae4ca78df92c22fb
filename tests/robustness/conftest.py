"""The hard-input corpus, written once per test session."""

from __future__ import annotations

import pytest

from tests.robustness.checks import corpus_cases
from tests.robustness.make_corpus import Case


@pytest.fixture(scope="session")
def cases(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Case]:
    """Every corpus case by name (synthetic ones written under a session temp folder)."""
    return corpus_cases(tmp_path_factory.mktemp("corpus"))
