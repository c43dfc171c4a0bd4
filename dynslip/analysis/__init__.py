"""Datasets to numbers or datasets: fronts, comparisons, convergence, the release test's metrics
(:mod:`dynslip.analysis.release`), the paper's numbers (:mod:`dynslip.analysis.paper`)."""
