"""Mechanism models: one interface (``Mechanism``) for serial D-H chains, URDF chains and the 3-PUPS."""
from .base import PRISMATIC, REVOLUTE, ErrorJacobian, Mechanism, ModelError, warm_up_kernels
from .dh import DHChain
from .loader import load_robot
from .urdf import URDFChain

__all__ = ["DHChain", "ErrorJacobian", "Mechanism", "ModelError", "PRISMATIC", "REVOLUTE", "URDFChain",
           "load_robot", "warm_up_kernels"]
