"""Relevance measures: how much each behaviour dimension tells about fitness, the
basis of weighted characterisations (:mod:`.measures` lists them all).

Layer: above :mod:`sdbc_evolution.characterise`, below transforms, ga and run.
"""
