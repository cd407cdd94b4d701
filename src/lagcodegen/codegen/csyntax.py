"""Helper: small pieces of C syntax shared by the emitters (literals, comments, records)."""
from __future__ import annotations


class EmitError(ValueError):
    """The kernels cannot be written as C; the message names the culprit."""


#: the spacing of 1.0 in each precision (machine epsilon)
UNIT_ROUNDOFF = {"double": 2.0 ** -52, "float": 2.0 ** -23}
#: a projection onto the constraints has converged when its last Newton step moved the coordinates
#: by no more than this many units of rounding of their largest magnitude (`<prefix>_project`)
PROJECTION_STALL = 8


def literal(value: float | int, real: str) -> str:
    text = repr(float(value))
    return text + "F" if real == "float" else text


def comment_text(text: str) -> str:
    """``text`` made safe inside a C block comment: no ``*/``, no ``/*``, one line."""
    return (str(text).replace("*/", "*\\/").replace("/*", "/\\*")
            .replace("\\n", "\\\\n").replace("\n", "\\n").replace("\r", "\\r"))


def record(result: str, name: str, arguments: str, doc: str, body: list, static: bool = False,
           hot: bool = False, shared: bool = False) -> dict:
    """A C function ``result name(arguments)`` for the templates, carrying its name (so the layout
    lists the exported functions without reading declarations); ``hot``: static and always inlined
    (LCG_HOT_INLINE); ``shared``: not exported either, but compiled once in lagcodegen's two-part
    build (LCG_SHARED: static in the one translation unit of the file as shipped)."""
    qualifier = "static LCG_HOT_INLINE " if hot else "LCG_SHARED " if shared else "static " if static else ""
    return {"decl": f"{qualifier}{result} {name}({arguments})", "name": name, "doc": doc, "body": body,
            "static": static or hot or shared, "hot": hot, "shared": shared}
