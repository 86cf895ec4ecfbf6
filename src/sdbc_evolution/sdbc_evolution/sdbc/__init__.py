"""Systematically derived behaviour characterisations (SDBC, section 3 of the paper)."""
