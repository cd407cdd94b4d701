"""Stage cli: the `lagcodegen` command (argument parsing apart from the commands)."""
