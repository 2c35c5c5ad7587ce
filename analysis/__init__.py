"""Analyses of experiments: statistics, figures, motion, report, VoxCAD export.

Computes on data it is given and opens no database: ``service`` reads the database into an
``ExperimentData`` (``service.reports.data.load_experiment``) and calls these modules.
Modules:

- ``analysis.data``: ``ExperimentData`` (pandas frames of the settings, runs,
  per-generation summaries and the initial and final populations);
- ``analysis.findings``: the findings, one declared primary measure per hypothesis, Holm
  within each family, verdicts by code (``findings.csv``); ``analysis.design`` their power,
  the runs a design needs, bootstrap intervals and Holm's thresholds, by simulation;
  ``analysis.rank_tests`` the Jonckheere-Terpstra and Mann-Whitney tests with exact p and Holm;
  ``analysis.run_summary`` one row per run (``summary.csv``);
  ``analysis.methods`` each treatment's evaluation in words;
- ``analysis.stats_tables``: t intervals over repetitions, the secondary pairwise tests
  between treatments and between start and end, Bonferroni per family;
- ``analysis.figures``: the report's figures as PNG + SVG (``FIGURES``);
- ``analysis.render``: 3-D voxel renders (active red, passive cyan);
- ``analysis.robots``: a stored record -> ``worker.tasks.Task`` -> phenotype and scene, as
  the workers built them;
- ``analysis.motion``: re-simulate a task or a stored record with frames
  (``worker.tasks.replay``) and animate it (GIF, MP4);
- ``analysis.report``: ``write_report(data, out_dir, robots=...)`` and ``report_html``
  (``service.reports.report`` binds them to a database);
- ``analysis.vxa``: ``scene_to_vxa(scene)`` / ``record_vxa(record)``, VoxCAD files.

Command line (``service/cli_analysis.py``)::

    softevo report EXPERIMENT --out DIR [--db URL] [--no-animation]
    softevo show INDIVIDUAL --out FILE.gif|FILE.mp4 [--environment land|water] [--db URL]
    softevo export-vxa INDIVIDUAL --out FILE.vxa [--environment land|water] [--db URL]
"""

if __name__ != "softevo.analysis":  # installed as softevo.analysis (pyproject.toml): one name, one module
    raise ImportError(f"import softevo.analysis, not {__name__}")
