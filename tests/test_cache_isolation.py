"""The suite never writes into the user's own kernel cache (issue 11: a module fixture of
tests/numeric/test_analyze.py used to compile into ~/.cache/lagcodegen)."""
from __future__ import annotations

from lagcodegen.native.cache import cache_dir


def test_every_test_compiles_into_the_session_tmp_dir(tmp_path_factory):
    # conftest's autouse session fixture exports LAGCODEGEN_CACHE_DIR before any test runs
    cache = cache_dir()
    assert cache.is_relative_to(tmp_path_factory.getbasetemp().resolve()), cache
