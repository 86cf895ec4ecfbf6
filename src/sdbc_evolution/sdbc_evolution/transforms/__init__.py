"""Transforms of raw behaviour vectors before novelty is scored: standardisation and
relevance weighting (:mod:`.pipeline`).

Layer: above :mod:`sdbc_evolution.relevance`, below ga and run.
"""
