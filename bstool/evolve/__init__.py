"""Evolution of the controllers: the paper's GA, §3.4 co-evolution, checkpoints, Dask backend."""
