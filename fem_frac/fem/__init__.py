"""Finite-element spaces, assembly of linear elasticity, loads and constraints."""
