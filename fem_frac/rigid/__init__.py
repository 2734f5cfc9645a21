"""Rigid bodies: mass properties, motion, ground contact."""
