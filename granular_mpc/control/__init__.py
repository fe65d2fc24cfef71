"""Controller: gait schedule and swing (``gait``, ``swing``), the centroidal-plus-sinkage
MPC (``mpc``), the whole-body controller (``wbc``), the controller's ground model
(``contact_model``), the control loop tick that composes them (``controller``) and our QP
types in front of ProxSuite (``solvers.proxqp``). See ``docs/controller.md``.
"""
