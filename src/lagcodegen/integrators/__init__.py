"""Stage integrators: the fixed-step schemes as data (tableaux, order conditions, the scheme registry); no C."""
