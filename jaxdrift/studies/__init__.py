"""The studies of the seed (section 2 point mass, section 4 half-car, Figs. 4-8) with their plots,
and the generators of virtual measurements. May import every layer below the CLI.
"""

from __future__ import annotations

from ._attgen import (
    make_attitude_run as make_attitude_run,
    write_attitude_csv as write_attitude_csv,
    DEFAULT_POSITIONS as DEFAULT_POSITIONS,
)
from ._pointmass import (
    pointmass_rhs as pointmass_rhs,
    pointmass_variance as pointmass_variance,
    pointmass_path as pointmass_path,
    pointmass_monte_carlo as pointmass_monte_carlo,
    pointmass_save_times as pointmass_save_times,
    chi2_interval as chi2_interval,
    euler_variance as euler_variance,
    slope_loglog as slope_loglog,
    run_pointmass_study as run_pointmass_study,
    plot_pointmass as plot_pointmass,
)
from ._rungen import (
    draw_effects as draw_effects,
    simulate_true_run as simulate_true_run,
    apply_sensor_effects as apply_sensor_effects,
    make_run as make_run,
    SIZES as SIZES,
    draw_sweep_case as draw_sweep_case,
)
from ._study import (
    SolverSpec as SolverSpec,
    SOLVER_LOOSE as SOLVER_LOOSE,
    SOLVER_TIGHT as SOLVER_TIGHT,
    SOLVER_FIXED as SOLVER_FIXED,
    StudyConfig as StudyConfig,
    VirtualMeasurement as VirtualMeasurement,
    virtual_measurement as virtual_measurement,
    simulate_forces as simulate_forces,
    simulate_prescribed_pitch as simulate_prescribed_pitch,
    drift_off_time as drift_off_time,
    run_force_paths as run_force_paths,
    run_pitch_paths as run_pitch_paths,
    run_paper_study as run_paper_study,
)

__all__ = ['DEFAULT_POSITIONS', 'SIZES', 'SOLVER_FIXED', 'SOLVER_LOOSE', 'SOLVER_TIGHT', 'SolverSpec', 'StudyConfig', 'VirtualMeasurement', 'apply_sensor_effects', 'chi2_interval', 'draw_effects', 'draw_sweep_case', 'drift_off_time', 'euler_variance', 'make_attitude_run', 'make_run', 'plot_pointmass', 'pointmass_monte_carlo', 'pointmass_path', 'pointmass_rhs', 'pointmass_save_times', 'pointmass_variance', 'run_force_paths', 'run_paper_study', 'run_pitch_paths', 'run_pointmass_study', 'simulate_forces', 'simulate_prescribed_pitch', 'simulate_true_run', 'slope_loglog', 'virtual_measurement', 'write_attitude_csv']
