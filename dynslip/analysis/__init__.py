"""Datasets to numbers or datasets: fronts, comparisons."""
