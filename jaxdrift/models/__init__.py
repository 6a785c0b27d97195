"""The equations: half-car (A.3)-(A.5) with the enforced moment, point mass (2.1), ISO 8608 roads,
quaternion kinematics (3.7)-(3.12), the accelerometer array (3.1), vehicle motion and gyro errors.
No solver, no plotting.
"""

from __future__ import annotations

from ._accel_array import (
    check_positions as check_positions,
    simulate_array as simulate_array,
    reconstruct as reconstruct,
    consistency_residual as consistency_residual,
    omega_dot_noise_matrix as omega_dot_noise_matrix,
    angle_error_std_closed_form as angle_error_std_closed_form,
)
from ._halfcar import (
    FORCE_STATE_NAMES as FORCE_STATE_NAMES,
    ROAD_STATE_NAMES as ROAD_STATE_NAMES,
    PITCH_STATE_NAMES as PITCH_STATE_NAMES,
    spring_forces as spring_forces,
    contact_forces as contact_forces,
    force_driven_rhs as force_driven_rhs,
    road_driven_rhs as road_driven_rhs,
    prescribed_pitch_rhs as prescribed_pitch_rhs,
    enforced_moment as enforced_moment,
    pitch_spring_torque as pitch_spring_torque,
    static_equilibrium as static_equilibrium,
    pitch_states_from_force_states as pitch_states_from_force_states,
    NonlinearSuspension as NonlinearSuspension,
    MountedMass as MountedMass,
    force_driven_mount_rhs as force_driven_mount_rhs,
)
from ._ins import (
    SmoothMotion as SmoothMotion,
    vehicle_motion as vehicle_motion,
    gyro_errors as gyro_errors,
)
from ._params import (
    HalfCarParams as HalfCarParams,
    PointMassParams as PointMassParams,
    PAPER_PERTURBATION as PAPER_PERTURBATION,
    PERTURBABLE_KEYS as PERTURBABLE_KEYS,
    random_perturbed_models as random_perturbed_models,
    stack_models as stack_models,
)
from ._pointmass import (
    pointmass_rhs as pointmass_rhs,
)
from ._quaternion import (
    B_MATRICES as B_MATRICES,
    skew as skew,
    rotation_matrix as rotation_matrix,
    omega_matrix as omega_matrix,
    quat_multiply as quat_multiply,
    quat_conjugate as quat_conjugate,
    quat_exp as quat_exp,
    euler_step as euler_step,
    expmap_step as expmap_step,
    quat_to_euler as quat_to_euler,
    euler_to_quat as euler_to_quat,
    rotation_angle_between as rotation_angle_between,
    ito_norm_growth as ito_norm_growth,
    euler_norm_growth as euler_norm_growth,
    angle_error_std as angle_error_std,
)
from ._road import (
    ISO8608_GD0 as ISO8608_GD0,
    ISO8608_N0 as ISO8608_N0,
    RoadProfile as RoadProfile,
    WheelInputs as WheelInputs,
    iso8608_road as iso8608_road,
    iso8608_psd as iso8608_psd,
    iso8608_variance as iso8608_variance,
)

__all__ = ['B_MATRICES', 'FORCE_STATE_NAMES', 'HalfCarParams', 'MountedMass', 'NonlinearSuspension', 'ISO8608_GD0', 'ISO8608_N0', 'PAPER_PERTURBATION', 'PERTURBABLE_KEYS', 'PITCH_STATE_NAMES', 'PointMassParams', 'ROAD_STATE_NAMES', 'RoadProfile', 'SmoothMotion', 'WheelInputs', 'angle_error_std', 'angle_error_std_closed_form', 'check_positions', 'consistency_residual', 'contact_forces', 'enforced_moment', 'euler_norm_growth', 'euler_step', 'euler_to_quat', 'expmap_step', 'force_driven_mount_rhs', 'force_driven_rhs', 'gyro_errors', 'iso8608_psd', 'iso8608_road', 'iso8608_variance', 'ito_norm_growth', 'omega_dot_noise_matrix', 'omega_matrix', 'pitch_spring_torque', 'pitch_states_from_force_states', 'pointmass_rhs', 'prescribed_pitch_rhs', 'quat_conjugate', 'quat_exp', 'quat_multiply', 'quat_to_euler', 'random_perturbed_models', 'reconstruct', 'road_driven_rhs', 'rotation_angle_between', 'rotation_matrix', 'simulate_array', 'skew', 'spring_forces', 'stack_models', 'static_equilibrium', 'vehicle_motion']
