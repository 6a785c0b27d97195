"""jaxdrift: Monte-Carlo drift analysis of force-driven multibody vehicle models in JAX.

The public API is re-exported here from private modules (see docs/architecture.md). Names are
imported lazily on first use (PEP 562), so ``import jaxdrift`` and ``jaxdrift --help`` do not pay
for importing JAX. jaxdrift never switches on float64 at import: call
``jax.config.update("jax_enable_x64", True)`` yourself (the CLI and the tests do).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__version__ = "0.1.0"

# public name -> (private module, name in that module)
_EXPORTS: dict[str, tuple[str, str]] = {}

# --- engine (#2) ---
_EXPORTS.update({
    "SampledSignal": ("_inputs", "SampledSignal"),
    "solve_sde": ("_sde", "solve_sde"),
    "RESULTS": ("_solve", "RESULTS"),
    "Result": ("_solve", "Result"),
    "Solution": ("_solve", "Solution"),
    "StepController": ("_solve", "StepController"),
    "solve_ode": ("_solve", "solve_ode"),
    "DOPRI5": ("_tableau", "DOPRI5"),
    "ButcherTableau": ("_tableau", "ButcherTableau"),
})

# --- noise and Monte-Carlo runner (#2) ---
_EXPORTS.update({
    "apply_input_effects": ("_noise", "apply_input_effects"),
    "path_normals": ("_noise", "path_normals"),
    "remove_input_effects": ("_noise", "remove_input_effects"),
    "white_noise": ("_noise", "white_noise"),
    "MCResult": ("_montecarlo", "MCResult"),
    "monte_carlo": ("_montecarlo", "monte_carlo"),
})

# --- models and paper study (#3) ---
_EXPORTS.update({
    "contact_forces": ("_halfcar", "contact_forces"),
    "enforced_moment": ("_halfcar", "enforced_moment"),
    "equilibrium_forces": ("_halfcar", "equilibrium_forces"),
    "force_driven_rhs": ("_halfcar", "force_driven_rhs"),
    "pitch_spring_torque": ("_halfcar", "pitch_spring_torque"),
    "pitch_states_from_force_states": ("_halfcar", "pitch_states_from_force_states"),
    "prescribed_pitch_rhs": ("_halfcar", "prescribed_pitch_rhs"),
    "road_driven_rhs": ("_halfcar", "road_driven_rhs"),
    "spring_forces": ("_halfcar", "spring_forces"),
    "static_equilibrium": ("_halfcar", "static_equilibrium"),
    "PAPER_PERTURBATION": ("_params", "PAPER_PERTURBATION"),
    "HalfCarParams": ("_params", "HalfCarParams"),
    "PointMassParams": ("_params", "PointMassParams"),
    "random_perturbed_models": ("_params", "random_perturbed_models"),
    "stack_models": ("_params", "stack_models"),
    "euler_variance": ("_pointmass", "euler_variance"),
    "pointmass_monte_carlo": ("_pointmass", "pointmass_monte_carlo"),
    "pointmass_path": ("_pointmass", "pointmass_path"),
    "pointmass_rhs": ("_pointmass", "pointmass_rhs"),
    "pointmass_variance": ("_pointmass", "pointmass_variance"),
    "run_pointmass_study": ("_pointmass", "run_pointmass_study"),
    "ISO8608_GD0": ("_road", "ISO8608_GD0"),
    "RoadProfile": ("_road", "RoadProfile"),
    "WheelInputs": ("_road", "WheelInputs"),
    "iso8608_psd": ("_road", "iso8608_psd"),
    "iso8608_road": ("_road", "iso8608_road"),
    "iso8608_variance": ("_road", "iso8608_variance"),
    "SOLVER_FIXED": ("_study", "SOLVER_FIXED"),
    "SOLVER_LOOSE": ("_study", "SOLVER_LOOSE"),
    "SOLVER_TIGHT": ("_study", "SOLVER_TIGHT"),
    "SolverSpec": ("_study", "SolverSpec"),
    "StudyConfig": ("_study", "StudyConfig"),
    "VirtualMeasurement": ("_study", "VirtualMeasurement"),
    "drift_off_time": ("_study", "drift_off_time"),
    "run_force_paths": ("_study", "run_force_paths"),
    "run_paper_study": ("_study", "run_paper_study"),
    "run_pitch_paths": ("_study", "run_pitch_paths"),
    "simulate_forces": ("_study", "simulate_forces"),
    "simulate_prescribed_pitch": ("_study", "simulate_prescribed_pitch"),
    "virtual_measurement": ("_study", "virtual_measurement"),
    "write_paper_outputs": ("_study", "write_paper_outputs"),
})

# --- variance (#4) ---
_EXPORTS.update({
    "solve_fixed_fast": ("_fast", "solve_fixed_fast"),
    "CovarianceResult": ("_variance", "CovarianceResult"),
    "brownian_intensity": ("_variance", "brownian_intensity"),
    "halfcar_free_mode_covariance": ("_variance", "halfcar_free_mode_covariance"),
    "halfcar_free_modes": ("_variance", "halfcar_free_modes"),
    "point_mass_covariance": ("_variance", "point_mass_covariance"),
    "point_mass_variance": ("_variance", "point_mass_variance"),
    "propagate_covariance": ("_variance", "propagate_covariance"),
    "quaternion_angle_variance": ("_variance", "quaternion_angle_variance"),
    "quaternion_norm_growth": ("_variance", "quaternion_norm_growth"),
    "quaternion_norm_sq_euler": ("_variance", "quaternion_norm_sq_euler"),
    "variance_interval": ("_variance", "variance_interval"),
})

# --- diagnosis (#5) ---
_EXPORTS.update({
    "InputError": ("_csvio", "InputError"),
    "VehicleRun": ("_csvio", "VehicleRun"),
    "read_model": ("_csvio", "read_model"),
    "read_vehicle_run": ("_csvio", "read_vehicle_run"),
    "write_vehicle_run": ("_csvio", "write_vehicle_run"),
    "diagnose_vehicle_run": ("_diagnose_vehicle", "diagnose_vehicle_run"),
})

# --- attitude (#6) ---
_EXPORTS.update({
    "check_positions": ("_accel_array", "check_positions"),
    "consistency_residual": ("_accel_array", "consistency_residual"),
    "reconstruct_from_accelerometers": ("_accel_array", "reconstruct"),
    "simulate_array": ("_accel_array", "simulate_array"),
    "run_attitude_diagnosis": ("_diagnose_attitude", "run_attitude_diagnosis"),
    "gyro_errors": ("_ins", "gyro_errors"),
    "vehicle_motion": ("_ins", "vehicle_motion"),
    "B_MATRICES": ("_quaternion", "B_MATRICES"),
    "angle_error_std": ("_quaternion", "angle_error_std"),
    "euler_step": ("_quaternion", "euler_step"),
    "expmap_step": ("_quaternion", "expmap_step"),
    "integrate_rates": ("_quaternion", "integrate_rates"),
    "ito_norm_growth": ("_quaternion", "ito_norm_growth"),
    "omega_matrix": ("_quaternion", "omega_matrix"),
    "quaternion_sde_paths": ("_quaternion", "quaternion_sde_paths"),
    "rotation_matrix": ("_quaternion", "rotation_matrix"),
})

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    try:
        module, attr = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'jaxdrift' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(f".{module}", __name__), attr)
    globals()[name] = value  # cache: later lookups skip __getattr__
    return value


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))


if TYPE_CHECKING:  # static analysers see the real imports
    from ._inputs import SampledSignal
    from ._sde import solve_sde
    from ._solve import RESULTS
    from ._solve import Result
    from ._solve import Solution
    from ._solve import StepController
    from ._solve import solve_ode
    from ._tableau import DOPRI5
    from ._tableau import ButcherTableau
    from ._noise import apply_input_effects
    from ._noise import path_normals
    from ._noise import remove_input_effects
    from ._noise import white_noise
    from ._montecarlo import MCResult
    from ._montecarlo import monte_carlo
    from ._halfcar import contact_forces
    from ._halfcar import enforced_moment
    from ._halfcar import equilibrium_forces
    from ._halfcar import force_driven_rhs
    from ._halfcar import pitch_spring_torque
    from ._halfcar import pitch_states_from_force_states
    from ._halfcar import prescribed_pitch_rhs
    from ._halfcar import road_driven_rhs
    from ._halfcar import spring_forces
    from ._halfcar import static_equilibrium
    from ._params import PAPER_PERTURBATION
    from ._params import HalfCarParams
    from ._params import PointMassParams
    from ._params import random_perturbed_models
    from ._params import stack_models
    from ._pointmass import euler_variance
    from ._pointmass import pointmass_monte_carlo
    from ._pointmass import pointmass_path
    from ._pointmass import pointmass_rhs
    from ._pointmass import pointmass_variance
    from ._pointmass import run_pointmass_study
    from ._road import ISO8608_GD0
    from ._road import RoadProfile
    from ._road import WheelInputs
    from ._road import iso8608_psd
    from ._road import iso8608_road
    from ._road import iso8608_variance
    from ._study import SOLVER_FIXED
    from ._study import SOLVER_LOOSE
    from ._study import SOLVER_TIGHT
    from ._study import SolverSpec
    from ._study import StudyConfig
    from ._study import VirtualMeasurement
    from ._study import drift_off_time
    from ._study import run_force_paths
    from ._study import run_paper_study
    from ._study import run_pitch_paths
    from ._study import simulate_forces
    from ._study import simulate_prescribed_pitch
    from ._study import virtual_measurement
    from ._study import write_paper_outputs
    from ._fast import solve_fixed_fast
    from ._variance import CovarianceResult
    from ._variance import brownian_intensity
    from ._variance import halfcar_free_mode_covariance
    from ._variance import halfcar_free_modes
    from ._variance import point_mass_covariance
    from ._variance import point_mass_variance
    from ._variance import propagate_covariance
    from ._variance import quaternion_angle_variance
    from ._variance import quaternion_norm_growth
    from ._variance import quaternion_norm_sq_euler
    from ._variance import variance_interval
    from ._csvio import InputError
    from ._csvio import VehicleRun
    from ._csvio import read_model
    from ._csvio import read_vehicle_run
    from ._csvio import write_vehicle_run
    from ._diagnose_vehicle import diagnose_vehicle_run
    from ._accel_array import check_positions
    from ._accel_array import consistency_residual
    from ._accel_array import reconstruct as reconstruct_from_accelerometers
    from ._accel_array import simulate_array
    from ._diagnose_attitude import run_attitude_diagnosis
    from ._ins import gyro_errors
    from ._ins import vehicle_motion
    from ._quaternion import B_MATRICES
    from ._quaternion import angle_error_std
    from ._quaternion import euler_step
    from ._quaternion import expmap_step
    from ._quaternion import integrate_rates
    from ._quaternion import ito_norm_growth
    from ._quaternion import omega_matrix
    from ._quaternion import quaternion_sde_paths
    from ._quaternion import rotation_matrix
