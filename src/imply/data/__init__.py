"""Datasets of the Section 5 study (rendered push clips)."""
