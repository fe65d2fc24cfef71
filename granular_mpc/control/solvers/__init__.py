"""QP solver adapters: our own problem/solution/status types in front of each backend
(``proxqp``: ProxSuite dense solver)."""
