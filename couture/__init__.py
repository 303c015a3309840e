"""couture: interactive garment design (Sensitive Couture) as a distributed system.

The library holds the shared science (pattern model, cloth energies, solvers,
body SDF, remeshing) and the bus and recording helpers; the processes in
``nodes/`` are thin adapters over it.
"""

__version__ = "0.1.0"
