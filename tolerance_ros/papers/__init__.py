"""Reproductions of the two source papers: their published figures beside this project's results."""
