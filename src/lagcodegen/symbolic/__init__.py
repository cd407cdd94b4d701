"""Stage symbolic: Model -> EquationsOfMotion (one module per derivation route)."""
