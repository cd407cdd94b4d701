"""Stage: CompiledSystem / Model -> files for other tools (FMI 2.0 and 3.0 FMUs, `export_fmu`)."""
from .fmu import FmuError, export_fmu

__all__ = ["FmuError", "export_fmu"]
