"""The replication study: the paper's experiments, figures and tables from one command.

- :mod:`.presets`: what a study holds and the sizes of its runs (``smoke``,
  ``local``, ``paper`` under ``configs/study/``);
- :mod:`.plan`: its runs, their directories and seeds, and how far each got;
- :mod:`.runner`: running them, resumable, locally or on Dask, with progress;
- :mod:`.measure`: a short probe of what a preset costs on this machine;
- the analysis, from the run directories alone: :mod:`.rundirs` (reading, and
  naming unusable runs), :mod:`.reduce` (the one pass over the full data, into the
  study's :mod:`.digest`, which is all the rest reads; :mod:`.combine` joins the
  digests of tasks run apart), :mod:`.quality` (curves,
  bests, Mann-Whitney U),
  :mod:`.relevance` (the MI table), :mod:`.exploration` (SOM maps), :mod:`.cost`
  (rates, and the paper's study on a cluster), :mod:`.claims` (the paper's claims
  and our verdicts), :mod:`.figures`, :mod:`.analysis` (tables and figures),
  :mod:`.report` (Markdown), :mod:`.compare` (two studies' verdicts side by side);
- :mod:`.cli`: ``sdbc-study`` / ``python -m sdbc_evolution.study``.
"""
