"""Figures and animations, drawn from saved tables and trial records only."""
