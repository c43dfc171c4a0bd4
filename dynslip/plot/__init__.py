"""Figures and animations, from datasets."""
