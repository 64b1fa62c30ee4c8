"""3D beam finite elements: materials, sections, the Timoshenko beam, and model assembly.

SI units throughout. Build a :class:`FEModel`, call :meth:`FEModel.assemble` to get an
:class:`AssembledSystem` (sparse ``M``, ``C``, ``K`` over the unclamped DOFs), then
:meth:`AssembledSystem.condense` to remove the massless DOFs statically.
"""
from .assembly import FEModel
from .beam import (beam_local_mass, beam_local_stiffness, beam_mass, beam_rotation,
                   beam_stiffness, beam_transformation, shear_parameters)
from .materials import Material, STEEL
from .sections import cowper_hollow_circle, GeneralSection, HollowCircular, SolidCircular
from .system import (AssembledSystem, component_index, Condensation, DOF_NAMES, DOFS_PER_NODE,
                     dense_symmetric_part, is_symmetric)

__all__ = ['AssembledSystem', 'Condensation', 'DOF_NAMES', 'DOFS_PER_NODE', 'FEModel',
           'GeneralSection', 'HollowCircular', 'Material', 'STEEL', 'SolidCircular',
           'beam_local_mass', 'beam_local_stiffness', 'beam_mass', 'beam_rotation',
           'beam_stiffness', 'beam_transformation', 'component_index', 'cowper_hollow_circle',
           'dense_symmetric_part', 'is_symmetric', 'shear_parameters']
