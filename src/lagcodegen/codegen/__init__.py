"""Stage codegen: EquationsOfMotion -> ReducedSystem -> CSources (reduce, print, render)."""
