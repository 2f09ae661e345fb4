"""Rendering for people: text tables and progress, PNG plots, the written accuracy report."""
