//! scanatlas-plugins: the built-in merge scorers, local solvers and packers, registered by name.
