"""The ``gistools`` command line (click)."""
