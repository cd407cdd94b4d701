"""Stage native: CSources -> CompiledSystem (compile with cffi, cache on disk)."""
