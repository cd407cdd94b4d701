"""Stage statics: EquationsOfMotion -> equilibria, linear models, consistent states."""
