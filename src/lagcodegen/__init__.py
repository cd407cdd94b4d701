"""lagcodegen: Lagrange's equations of mechanical systems, emitted as fast standalone C.

Pipeline (one module per stage, data flows one way)::

    Model --derive_equations--> EquationsOfMotion --reduce_expressions--> ReducedKernel
          --render_sources--> CSources --build_module--> CompiledSystem --simulate/sweep--> arrays
"""
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

from .model import Model, ModelError
from .symbolic.derive import EquationsOfMotion, derive_equations
from .tree import Link

try:
    __version__ = _version("lagcodegen")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0.1.0"

__all__ = ["Model", "ModelError", "Link", "EquationsOfMotion", "derive_equations", "__version__"]
