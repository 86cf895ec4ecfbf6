"""sdbc_evolution: systematic behaviour characterisations, novelty search and the GA."""
