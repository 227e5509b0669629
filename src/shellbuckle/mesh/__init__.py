"""Meshes: icosahedral and randomized spheres, topology, checks and file formats."""

from .checks import MeshQuality, mesh_quality, validate_surface
from .icosphere import icosphere
from .io import read_mesh, write_mesh
from .mesh import Mesh
from .random_sphere import random_sphere
from .topology import MeshError, Topology

__all__ = ["Mesh", "MeshError", "MeshQuality", "Topology", "icosphere", "mesh_quality",
           "random_sphere", "read_mesh", "validate_surface", "write_mesh"]
