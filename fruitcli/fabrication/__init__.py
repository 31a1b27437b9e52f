"""Fabrication: the molds that cast the pieces of the touch skin."""
