"""Statics: equilibrium branches of an elastica carrying a drop (see wet_elastica)."""
