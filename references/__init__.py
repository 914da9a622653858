"""PyTorch reference implementations of the seeds' SACs, for the equivalence tests and the
benchmarks that compare against PyTorch.

One module per seed family, each written from the seed's code and prose with the blanks filled
in, and with one change: every random draw (the reparameterisation noise eps) is an argument, so
the JAX side and the reference see the same eps.

    cleanrl_sac   seed 002 (CleanRL-style SAC v2)        preset "cleanrl"
    pendulum_sac  seed 001 (Pendulum notebook, SAC v2)    preset "pendulum"
    sac_v1        seeds 000/003 (SAC v1, value network)   preset "v1"

`transfer` moves weights between these modules and Flax parameter trees.
"""
