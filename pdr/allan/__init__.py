"""Allan-variance characterisation of inertial sensors (seed 004, Sec. 2).

Modules, one concept each:

``taus``            averaging factors m (tau = m / rate): log-spaced with a density, or all
``estimators``      non-overlapping (seed 004 eq. 1), overlapping and modified Allan variance
``confidence``      equivalent degrees of freedom (Greenhall) and chi-square intervals
``noise_model``     IEEE noise model AVAR = 3Q^2/tau^2 + N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3 + R^2 tau^2/2, WLS fit
``slopes``          classic slope readings (-1/2 line at 1 s, minimum / 0.664, +1/2 line at 3 s)
``units``           SI and datasheet units
``grade``           sensor grade from seed 004 Table 1
``pdr_impact``      PDR error growth from gyro bias and scale factor (seed 004 eqs. 20-22, Tables 3-4)
``filter_params``   noise parameters for filters and a Kalibr-style imu.yaml
``record_checks``   sampling, gaps and motion checks of a static record
``synthetic``       simulated sensor noise with known terms (seed 004 eqs. 3-4, flicker)
``characterise``    the whole analysis of one sensor / one recording
``plots``, ``html_report``, ``report``   the report files (PNG, HTML, JSON)
"""

from pdr.allan.estimators import AllanCurve, allan_curve, avar_modified, avar_nonoverlapping, avar_overlapping
from pdr.allan.noise_model import NoiseFit, fit_noise_model
from pdr.allan.taus import averaging_factors

__all__ = [
    "AllanCurve", "NoiseFit", "allan_curve", "averaging_factors", "avar_modified", "avar_nonoverlapping",
    "avar_overlapping", "fit_noise_model",
]
