"""The finite-element core: reference elements, meshes and the gmsh wrapper, solids, energy
terms, IPC contact, the linear solver, Newton and the load path. Knows nothing about hydrogels
or actuators; imports only :mod:`hydrojam.materials`' protocol."""
