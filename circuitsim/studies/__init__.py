"""Studies past one sweep: parameter grids (:mod:`.grid`), their runs and results
(:mod:`.study`), and their execution in-process or on a Dask cluster (:mod:`.execution`); the
hunting bifurcation diagram, speed swept up then down on the ODE and the circuit
(:mod:`.hunting`, its results :mod:`.hunting_result`, its files :mod:`.hunting_plot`); Monte
Carlo over part tolerances and op-amp offsets (:mod:`.tolerance`)."""
