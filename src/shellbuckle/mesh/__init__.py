"""Meshes: icosahedral and randomized spheres, topology, checks and file formats."""

from .icosphere import icosphere
from .mesh import Mesh
from .topology import MeshError, Topology

__all__ = ["Mesh", "MeshError", "Topology", "icosphere"]
