"""The paper's Section IV: its sweeps (``study``), its statements as data checked against hydrojam
(``claims``), the figures (``figures``), ``report.md`` (``report``) and the whole run
(``reproduce``)."""
