"""One read -> compute -> write function per product; the CLI, the library and QGIS call only these."""
