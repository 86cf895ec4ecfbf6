"""Running an experiment: configuration, evaluators, results, checkpoints and
sdbc-evolve."""
