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

# --- engine ---
_EXPORTS.update({
    "SampledSignal": ("solvers._inputs", "SampledSignal"),
    "solve_sde": ("solvers._sde", "solve_sde"),
    "RESULTS": ("solvers._solve", "RESULTS"),
    "Result": ("solvers._solve", "Result"),
    "Solution": ("solvers._solve", "Solution"),
    "StepController": ("solvers._solve", "StepController"),
    "solve_ode": ("solvers._solve", "solve_ode"),
    "DOPRI5": ("solvers._tableau", "DOPRI5"),
    "ButcherTableau": ("solvers._tableau", "ButcherTableau"),
})

# --- noise and Monte-Carlo runner ---
_EXPORTS.update({
    "apply_input_effects": ("ensemble._noise", "apply_input_effects"),
    "path_normals": ("ensemble._noise", "path_normals"),
    "remove_input_effects": ("ensemble._noise", "remove_input_effects"),
    "white_noise": ("ensemble._noise", "white_noise"),
    "MCResult": ("ensemble._montecarlo", "MCResult"),
    "monte_carlo": ("ensemble._montecarlo", "monte_carlo"),
})

# --- models and paper study ---
_EXPORTS.update({
    "contact_forces": ("models._halfcar", "contact_forces"),
    "enforced_moment": ("models._halfcar", "enforced_moment"),
    "equilibrium_forces": ("models._halfcar", "equilibrium_forces"),
    "force_driven_rhs": ("models._halfcar", "force_driven_rhs"),
    "pitch_spring_torque": ("models._halfcar", "pitch_spring_torque"),
    "pitch_states_from_force_states": ("models._halfcar", "pitch_states_from_force_states"),
    "prescribed_pitch_rhs": ("models._halfcar", "prescribed_pitch_rhs"),
    "road_driven_rhs": ("models._halfcar", "road_driven_rhs"),
    "spring_forces": ("models._halfcar", "spring_forces"),
    "static_equilibrium": ("models._halfcar", "static_equilibrium"),
    "PAPER_PERTURBATION": ("models._params", "PAPER_PERTURBATION"),
    "HalfCarParams": ("models._params", "HalfCarParams"),
    "PointMassParams": ("models._params", "PointMassParams"),
    "random_perturbed_models": ("models._params", "random_perturbed_models"),
    "stack_models": ("models._params", "stack_models"),
    "euler_variance": ("analysis._pointmass", "euler_variance"),
    "pointmass_monte_carlo": ("studies._pointmass", "pointmass_monte_carlo"),
    "pointmass_path": ("studies._pointmass", "pointmass_path"),
    "pointmass_rhs": ("models._pointmass", "pointmass_rhs"),
    "pointmass_variance": ("analysis._pointmass", "pointmass_variance"),
    "run_pointmass_study": ("studies._pointmass", "run_pointmass_study"),
    "ISO8608_GD0": ("models._road", "ISO8608_GD0"),
    "RoadProfile": ("models._road", "RoadProfile"),
    "WheelInputs": ("models._road", "WheelInputs"),
    "iso8608_psd": ("models._road", "iso8608_psd"),
    "iso8608_road": ("models._road", "iso8608_road"),
    "iso8608_variance": ("models._road", "iso8608_variance"),
    "SOLVER_FIXED": ("studies._study", "SOLVER_FIXED"),
    "SOLVER_LOOSE": ("studies._study", "SOLVER_LOOSE"),
    "SOLVER_TIGHT": ("studies._study", "SOLVER_TIGHT"),
    "SolverSpec": ("studies._study", "SolverSpec"),
    "StudyConfig": ("studies._study", "StudyConfig"),
    "VirtualMeasurement": ("studies._study", "VirtualMeasurement"),
    "drift_off_time": ("studies._paper_summary", "drift_off_time"),
    "run_force_paths": ("studies._study", "run_force_paths"),
    "run_paper_study": ("studies._study", "run_paper_study"),
    "run_pitch_paths": ("studies._study", "run_pitch_paths"),
    "simulate_forces": ("studies._study", "simulate_forces"),
    "simulate_prescribed_pitch": ("studies._study", "simulate_prescribed_pitch"),
    "virtual_measurement": ("studies._study", "virtual_measurement"),
    "write_paper_outputs": ("studies._paper_plots", "write_paper_outputs"),
})

# --- variance ---
_EXPORTS.update({
    "solve_fixed_fast": ("solvers._fast", "solve_fixed_fast"),
    "CovarianceResult": ("analysis._variance", "CovarianceResult"),
    "brownian_intensity": ("analysis._variance", "brownian_intensity"),
    "halfcar_free_mode_covariance": ("analysis._variance", "halfcar_free_mode_covariance"),
    "halfcar_free_modes": ("analysis._variance", "halfcar_free_modes"),
    "point_mass_covariance": ("analysis._variance", "point_mass_covariance"),
    "point_mass_variance": ("analysis._variance", "point_mass_variance"),
    "propagate_covariance": ("analysis._variance", "propagate_covariance"),
    "quaternion_angle_variance": ("analysis._variance", "quaternion_angle_variance"),
    "quaternion_norm_growth": ("analysis._variance", "quaternion_norm_growth"),
    "quaternion_norm_sq_euler": ("analysis._variance", "quaternion_norm_sq_euler"),
    "variance_interval": ("analysis._variance", "variance_interval"),
})

# --- diagnosis ---
_EXPORTS.update({
    "InputError": ("io._csvio", "InputError"),
    "VehicleRun": ("io._csvio", "VehicleRun"),
    "read_model": ("io._csvio", "read_model"),
    "read_vehicle_run": ("io._csvio", "read_vehicle_run"),
    "write_vehicle_run": ("io._csvio", "write_vehicle_run"),
    "load_run": ("io._runs", "load_run"),
    "AttitudeRun": ("io._runs", "AttitudeRun"),
    "diagnose_vehicle_run": ("diagnosis.vehicle._pipeline", "diagnose_vehicle_run"),
})

# --- attitude ---
_EXPORTS.update({
    "check_positions": ("models._accel_array", "check_positions"),
    "consistency_residual": ("models._accel_array", "consistency_residual"),
    "reconstruct_from_accelerometers": ("models._accel_array", "reconstruct"),
    "simulate_array": ("models._accel_array", "simulate_array"),
    "run_attitude_diagnosis": ("diagnosis.attitude._diagnose", "run_attitude_diagnosis"),
    "gyro_errors": ("models._ins", "gyro_errors"),
    "vehicle_motion": ("models._ins", "vehicle_motion"),
    "B_MATRICES": ("models._quaternion", "B_MATRICES"),
    "angle_error_std": ("models._quaternion", "angle_error_std"),
    "euler_step": ("models._quaternion", "euler_step"),
    "expmap_step": ("models._quaternion", "expmap_step"),
    "integrate_rates": ("analysis._attitude_paths", "integrate_rates"),
    "ito_norm_growth": ("models._quaternion", "ito_norm_growth"),
    "omega_matrix": ("models._quaternion", "omega_matrix"),
    "quaternion_sde_paths": ("analysis._attitude_paths", "quaternion_sde_paths"),
    "rotation_matrix": ("models._quaternion", "rotation_matrix"),
})

# --- durability ---
_EXPORTS.update({
    "DurabilityResult": ("durability._analysis", "DurabilityResult"),
    "durability_analysis": ("durability._analysis", "durability_analysis"),
    "section_forces": ("durability._analysis", "section_forces"),
    "pitch_spring_rule": ("durability._variants", "pitch_spring_rule"),
    "rainflow_cycles": ("durability._damage", "rainflow_cycles"),
    "pseudo_damage": ("durability._damage", "pseudo_damage"),
})

# --- the engine against the machine's limit ---
_EXPORTS.update({
    "use_all_cores": ("ensemble._devices", "use_all_cores"),
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
    from .solvers._inputs import SampledSignal
    from .solvers._sde import solve_sde
    from .solvers._solve import RESULTS
    from .solvers._solve import Result
    from .solvers._solve import Solution
    from .solvers._solve import StepController
    from .solvers._solve import solve_ode
    from .solvers._tableau import DOPRI5
    from .solvers._tableau import ButcherTableau
    from .ensemble._noise import apply_input_effects
    from .ensemble._noise import path_normals
    from .ensemble._noise import remove_input_effects
    from .ensemble._noise import white_noise
    from .ensemble._montecarlo import MCResult
    from .ensemble._montecarlo import monte_carlo
    from .models._halfcar import contact_forces
    from .models._halfcar import enforced_moment
    from .models._halfcar import equilibrium_forces
    from .models._halfcar import force_driven_rhs
    from .models._halfcar import pitch_spring_torque
    from .models._halfcar import pitch_states_from_force_states
    from .models._halfcar import prescribed_pitch_rhs
    from .models._halfcar import road_driven_rhs
    from .models._halfcar import spring_forces
    from .models._halfcar import static_equilibrium
    from .models._params import PAPER_PERTURBATION
    from .models._params import HalfCarParams
    from .models._params import PointMassParams
    from .models._params import random_perturbed_models
    from .models._params import stack_models
    from .analysis._pointmass import euler_variance
    from .studies._pointmass import pointmass_monte_carlo
    from .studies._pointmass import pointmass_path
    from .models._pointmass import pointmass_rhs
    from .analysis._pointmass import pointmass_variance
    from .studies._pointmass import run_pointmass_study
    from .models._road import ISO8608_GD0
    from .models._road import RoadProfile
    from .models._road import WheelInputs
    from .models._road import iso8608_psd
    from .models._road import iso8608_road
    from .models._road import iso8608_variance
    from .studies._study import SOLVER_FIXED
    from .studies._study import SOLVER_LOOSE
    from .studies._study import SOLVER_TIGHT
    from .studies._study import SolverSpec
    from .studies._study import StudyConfig
    from .studies._study import VirtualMeasurement
    from .studies._paper_summary import drift_off_time
    from .studies._study import run_force_paths
    from .studies._study import run_paper_study
    from .studies._study import run_pitch_paths
    from .studies._study import simulate_forces
    from .studies._study import simulate_prescribed_pitch
    from .studies._study import virtual_measurement
    from .studies._paper_plots import write_paper_outputs
    from .solvers._fast import solve_fixed_fast
    from .analysis._variance import CovarianceResult
    from .analysis._variance import brownian_intensity
    from .analysis._variance import halfcar_free_mode_covariance
    from .analysis._variance import halfcar_free_modes
    from .analysis._variance import point_mass_covariance
    from .analysis._variance import point_mass_variance
    from .analysis._variance import propagate_covariance
    from .analysis._variance import quaternion_angle_variance
    from .analysis._variance import quaternion_norm_growth
    from .analysis._variance import quaternion_norm_sq_euler
    from .analysis._variance import variance_interval
    from .io._csvio import InputError
    from .io._csvio import VehicleRun
    from .io._csvio import read_model
    from .io._csvio import read_vehicle_run
    from .io._csvio import write_vehicle_run
    from .io._runs import AttitudeRun, load_run
    from .diagnosis.vehicle._pipeline import diagnose_vehicle_run
    from .models._accel_array import check_positions
    from .models._accel_array import consistency_residual
    from .models._accel_array import reconstruct as reconstruct_from_accelerometers
    from .models._accel_array import simulate_array
    from .diagnosis.attitude._diagnose import run_attitude_diagnosis
    from .models._ins import gyro_errors
    from .models._ins import vehicle_motion
    from .models._quaternion import B_MATRICES
    from .models._quaternion import angle_error_std
    from .models._quaternion import euler_step
    from .models._quaternion import expmap_step
    from .analysis._attitude_paths import integrate_rates
    from .models._quaternion import ito_norm_growth
    from .models._quaternion import omega_matrix
    from .analysis._attitude_paths import quaternion_sde_paths
    from .models._quaternion import rotation_matrix
    from .durability._analysis import DurabilityResult
    from .durability._analysis import durability_analysis
    from .durability._analysis import section_forces
    from .durability._variants import pitch_spring_rule
    from .durability._damage import rainflow_cycles
    from .durability._damage import pseudo_damage
    from .ensemble._devices import use_all_cores
