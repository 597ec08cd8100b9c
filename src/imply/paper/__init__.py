"""Paper outputs: macros, numbers, tables, figures and the reproduction report."""
