"""Characterisations as parts: characterisers observe the engine and turn each
controller's trials into a named behaviour vector (:mod:`.registry` lists them all).

Layer: above :mod:`sdbc_evolution.sdbc`, below relevance, transforms, ga and run.
"""
