"""Fixtures every test module may ask for."""

from __future__ import annotations

import pytest

from tests.real_cases import Cases, shared_root


@pytest.fixture(scope="session")
def real_case(tmp_path_factory) -> Cases:  # type: ignore[no-untyped-def]
    """``real_case(name)``: a real log imported and exported once per run (tests/real_cases.py)."""
    return Cases(shared_root(tmp_path_factory))
