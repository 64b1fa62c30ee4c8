"""Modal reduction, free/stuck impactor bases and linear stability (no rclpy)."""
from impact_damper_sim.modal.basis import (
    ModalBasis,
    full_harmonic_response,
    harmonic_response,
    modal_reduction,
)
from impact_damper_sim.modal.stability import (
    least_damped_eigenvalue,
    onset_cross_coupling,
    state_matrix,
)
from impact_damper_sim.modal.stuck import (
    StuckTransforms,
    add_point_mass,
    round_trip_error,
    stuck_basis,
    switch_matrices,
)

__all__ = ['ModalBasis', 'StuckTransforms', 'add_point_mass', 'full_harmonic_response',
           'harmonic_response', 'least_damped_eigenvalue', 'modal_reduction',
           'onset_cross_coupling', 'round_trip_error', 'state_matrix', 'stuck_basis',
           'switch_matrices']
