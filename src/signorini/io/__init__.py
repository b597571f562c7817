"""The command line, case files, result directories and field output."""
