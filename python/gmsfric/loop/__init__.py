"""Residual-driven identification loop (issue 5)."""
