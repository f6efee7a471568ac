"""``bstool campaign``: a plan of evolve runs (models × seeds) with the paper's analyses on each,
run step by step and resumable, and a report with statistics over the seeds (docs/campaign.md).

``plan`` parses and checks the plan file, ``runner`` evolves its runs through the evolve
driver, ``record`` keeps what was done (wall times, a lock), ``analyses`` computes and caches
the experiments per run, ``stats`` and ``claims`` turn them into the paper's verdicts, and
``report`` / ``figures`` write DIR/report.
"""
