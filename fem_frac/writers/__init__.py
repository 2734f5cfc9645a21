"""Files a run writes: the VTK time series (``.pvd`` + ``.vtu``), summary and resolved case."""
