"""Example inputs from gistools' own generators (gistools examples)."""
