"""jaxdrift: Monte-Carlo drift analysis of force-driven multibody vehicle models in JAX.

The public API is re-exported here from private modules (see docs/architecture.md).
jaxdrift never switches on float64 at import: call ``jax.config.update("jax_enable_x64", True)``
yourself (the CLI and the tests do).
"""

__version__ = "0.1.0"

# --- engine (#2) ---
from ._inputs import SampledSignal
from ._sde import solve_sde
from ._solve import RESULTS, Result, Solution, StepController, solve_ode
from ._tableau import DOPRI5, ButcherTableau

# --- noise and Monte-Carlo runner (#2) ---
from ._noise import apply_input_effects, path_normals, remove_input_effects, white_noise
from ._montecarlo import MCResult, monte_carlo

# --- models and paper study (#3) ---
from ._halfcar import (
    contact_forces,
    enforced_moment,
    equilibrium_forces,
    force_driven_rhs,
    pitch_spring_torque,
    pitch_states_from_force_states,
    prescribed_pitch_rhs,
    road_driven_rhs,
    spring_forces,
    static_equilibrium,
)
from ._params import (
    PAPER_PERTURBATION,
    HalfCarParams,
    PointMassParams,
    random_perturbed_models,
    stack_models,
)
from ._pointmass import (
    euler_variance,
    pointmass_monte_carlo,
    pointmass_path,
    pointmass_rhs,
    pointmass_variance,
    run_pointmass_study,
)
from ._road import ISO8608_GD0, RoadProfile, WheelInputs, iso8608_psd, iso8608_road, iso8608_variance
from ._study import (
    SOLVER_FIXED,
    SOLVER_LOOSE,
    SOLVER_TIGHT,
    SolverSpec,
    StudyConfig,
    VirtualMeasurement,
    drift_off_time,
    run_force_paths,
    run_paper_study,
    run_pitch_paths,
    simulate_forces,
    simulate_prescribed_pitch,
    virtual_measurement,
    write_paper_outputs,
)

# --- variance (#4) ---
from ._fast import solve_fixed_fast
from ._variance import (
    CovarianceResult,
    brownian_intensity,
    halfcar_free_mode_covariance,
    halfcar_free_modes,
    point_mass_covariance,
    point_mass_variance,
    propagate_covariance,
    quaternion_angle_variance,
    quaternion_norm_growth,
    quaternion_norm_sq_euler,
    variance_interval,
)

# --- diagnosis (#5) ---
from ._csvio import InputError, VehicleRun, read_model, read_vehicle_run, write_vehicle_run
from ._diagnose_vehicle import diagnose_vehicle_run

# --- attitude (#6) ---
from ._accel_array import check_positions, consistency_residual, reconstruct as reconstruct_from_accelerometers, simulate_array
from ._diagnose_attitude import run_attitude_diagnosis
from ._ins import gyro_errors, vehicle_motion
from ._quaternion import (
    B_MATRICES,
    angle_error_std,
    euler_step,
    expmap_step,
    integrate_rates,
    ito_norm_growth,
    omega_matrix,
    quaternion_sde_paths,
    rotation_matrix,
)
