"""The offline web map page (page.py) and the map library it inlines (vendor/)."""
