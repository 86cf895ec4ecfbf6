"""The genetic algorithm: novelty, the archive, rankings, selection, mutation and
treatments."""
