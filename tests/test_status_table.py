"""One status table (src/lagcodegen/status.py) behind the C defines, the Python enum and the docs."""
from __future__ import annotations

import re

from lagcodegen import catalog, derive_equations
from lagcodegen.codegen.reduce import reduce_expressions
from lagcodegen.codegen.render import render_sources
from lagcodegen.run.sweep import CHUNK_FAILED, NOT_RUN
from lagcodegen.status import STATUS_TABLE, SWEEP_STATUS_TABLE, Status, status_markdown


def test_docs_status_page_is_current(repo_root):
    committed = (repo_root / "docs" / "status.md").read_text()
    assert committed == status_markdown(), "run: python -c \"from lagcodegen.status import status_markdown; " \
                                           "open('docs/status.md', 'w').write(status_markdown())\""


def test_generated_header_defines_exactly_the_table():
    sources = render_sources(reduce_expressions(derive_equations(catalog.double_pendulum()), ["rhs"]))
    defines = dict(re.findall(r"#define (LCG_[A-Z_]+) (-?\d+)", sources.header))
    status_defines = {name: int(code) for name, code in defines.items() if name in {r.c_name for r in STATUS_TABLE}}
    assert status_defines == {row.c_name: row.code for row in STATUS_TABLE}
    for row in STATUS_TABLE:  # the header documents each code with the table's message
        assert row.message in sources.header.replace("\n * ", " "), row.name


def test_python_enum_and_sweep_codes_follow_the_table():
    assert [(s.name, int(s), s.message) for s in Status] == [(r.name, r.code, r.message) for r in STATUS_TABLE]
    assert (NOT_RUN, CHUNK_FAILED) == tuple(row.code for row in SWEEP_STATUS_TABLE)
    codes = [row.code for row in STATUS_TABLE + SWEEP_STATUS_TABLE]
    assert len(set(codes)) == len(codes)
