"""The paper's Section IV: its sweeps, its statements checked against hydrojam, figures and the
report."""
