"""Studies past one sweep: parameter grids (:mod:`.grid`), their runs and results
(:mod:`.study`), and their execution in-process or on a Dask cluster (:mod:`.execution`)."""
