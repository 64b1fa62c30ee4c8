"""3D beam finite elements: materials, sections, the Timoshenko beam, and model assembly.

SI units throughout. Build a :class:`FEModel`, call :meth:`FEModel.assemble` to get an
:class:`AssembledSystem` (sparse ``M``, ``C``, ``K`` over the unclamped DOFs), then
:meth:`AssembledSystem.condense` to remove the massless DOFs statically.
"""
from .assembly import FEModel
from .beam import (
    beam_local_mass,
    beam_local_stiffness,
    beam_mass,
    beam_rotation,
    beam_stiffness,
    beam_transformation,
    shear_parameters,
)
from .materials import STEEL, Material
from .sections import GeneralSection, HollowCircular, SolidCircular, cowper_hollow_circle
from .system import (
    DOF_NAMES,
    DOFS_PER_NODE,
    AssembledSystem,
    Condensation,
    component_index,
    dense_symmetric_part,
    is_symmetric,
)

__all__ = ['AssembledSystem', 'Condensation', 'DOF_NAMES', 'DOFS_PER_NODE', 'FEModel',
           'GeneralSection', 'HollowCircular', 'Material', 'STEEL', 'SolidCircular',
           'beam_local_mass', 'beam_local_stiffness', 'beam_mass', 'beam_rotation',
           'beam_stiffness', 'beam_transformation', 'component_index', 'cowper_hollow_circle',
           'dense_symmetric_part', 'is_symmetric', 'shear_parameters']
