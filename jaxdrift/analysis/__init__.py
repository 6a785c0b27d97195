"""Closed forms and covariance propagation of the drift variances ((2.8), (2.11), (3.14), the
half-car free mode) and the integration of the attitude kinematics. Imports models and solvers.
"""

from __future__ import annotations

from ._attitude_paths import (
    integrate_rates as integrate_rates,
    quaternion_sde_paths as quaternion_sde_paths,
)
from ._pointmass import (
    pointmass_variance as pointmass_variance,
    euler_variance as euler_variance,
)
from ._variance import (
    brownian_intensity as brownian_intensity,
    variance_interval as variance_interval,
    point_mass_variance as point_mass_variance,
    point_mass_covariance as point_mass_covariance,
    quaternion_norm_growth as quaternion_norm_growth,
    quaternion_norm_sq_euler as quaternion_norm_sq_euler,
    quaternion_angle_variance as quaternion_angle_variance,
    halfcar_free_modes as halfcar_free_modes,
    halfcar_free_mode_covariance as halfcar_free_mode_covariance,
    CovarianceResult as CovarianceResult,
    propagate_covariance as propagate_covariance,
)

__all__ = ['CovarianceResult', 'brownian_intensity', 'euler_variance', 'halfcar_free_mode_covariance', 'halfcar_free_modes', 'integrate_rates', 'point_mass_covariance', 'point_mass_variance', 'pointmass_variance', 'propagate_covariance', 'quaternion_angle_variance', 'quaternion_norm_growth', 'quaternion_norm_sq_euler', 'quaternion_sde_paths', 'variance_interval']
