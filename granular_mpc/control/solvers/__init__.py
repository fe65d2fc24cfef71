"""QP solver adapters: our own problem/solution/status types in front of each backend
(``proxqp``: ProxSuite dense solver, and the types; ``daqp``: DAQP's dual active-set
solver with the same contract)."""
