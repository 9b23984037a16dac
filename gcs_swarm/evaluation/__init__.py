"""Evaluation: paper-style run figures, variant comparisons, Monte Carlo campaigns of real lockstep flights.

- `signals`: relative angles, commanded attitude rates, cruise figures derived from a run's logs (spec 10).
- `figures`: matplotlib figures in the paper's style (optional extra `plot`).
- `variants`: mission files derived for a variant (method, controller, wind) or randomised (Monte Carlo).
- `flights`: fly one derived mission on free ports; its report figures as a flat result.
- `compare`: `gcs-swarm compare`, the same mission under each variant, side by side.
- `montecarlo` + `campaign_store`: `gcs-swarm montecarlo`, resumable campaigns on local processes or Dask.
"""
