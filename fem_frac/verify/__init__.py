"""Declared references: closed-form solutions and the error of a run against them."""
