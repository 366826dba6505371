"""IMU noise files users already have, read into the filter model (``imu_noise_file``).

Three conventions, all in SI units (continuous-time densities, as Kalibr defines them):

* **Kalibr** ``imu.yaml`` (allan_variance_ros writes it): top-level
  ``gyroscope_noise_density`` (rad/s/sqrt(Hz)), ``gyroscope_random_walk``
  (rad/s^2/sqrt(Hz)), ``accelerometer_noise_density`` (m/s^2/sqrt(Hz)),
  ``accelerometer_random_walk`` (m/s^3/sqrt(Hz)) and ``update_rate`` (Hz);
* **OpenVINS** ``kalibr_imu_chain.yaml``: the same keys under ``imu0`` (the one IMU
  entry, or ``imu0`` among several);
* **VINS-Fusion** config (OpenCV YAML, ``%YAML:1.0``): ``gyr_n``, ``gyr_w``, ``acc_n``,
  ``acc_w`` in the same units (no rate key).

What each becomes (:func:`model_values`; :data:`~sins_align_ros.units.DPSH`,
:data:`~sins_align_ros.units.DPH`, :data:`~sins_align_ros.units.UG` are the model's units):

* white noise, one for one: ``gyro_arw_dpsh = n_g / DPSH`` (rad/s/sqrt(Hz) = rad/sqrt(s);
  x 180/pi x 60 gives deg/sqrt(h)) and ``accel_vrw_ug_rthz = n_a / UG``;
* the gyro bias random walk ``w_g`` (its variance grows as ``w_g^2 t``) becomes the model's
  first-order Gauss-Markov bias ``gyro_bias_instability_dph`` with the same driving
  noise: ``sigma = w_g sqrt(tau_g / 2)``, ``tau_g = gyro_bias_tau_s``. A Markov process of
  sigma and tau is driven by ``2 sigma^2 / tau`` per second, so up to a few tenths of tau
  it *is* the random walk; beyond, it stays bounded where the walk would not;
* the accelerometer bias random walk ``w_a``: the model has no slowly varying accelerometer
  part beside the bias, so the bias 1-sigma ``accel_bias_ug`` takes the walk's growth over
  ``accel_bias_tau_s / 2`` added to the turn-on part (the value set, default 100 micro-g)
  in quadrature: ``sqrt(b^2 + w_a^2 tau_a / 2)``. The GNSS-aided filters hold that bias
  as a Markov process of ``tau_a`` whose driving noise, ``2 sigma^2 / tau_a``, is then
  at least ``w_a^2``; the still-base filters hold it constant, which covers the walk
  over an alignment shorter than ``tau_a / 2`` (30 min by default).

The files carry no turn-on bias: ``gyro_bias_dph`` keeps its value, and the self-check
raises the biases to the class the measured noise shows (:mod:`~sins_align_ros.align.
inputs.self_check`), as it widens a file's noise that the data contradict.

Values given as parameters (a params file, ``-p``, ``--set``) win over the file's.
"""
import math
from dataclasses import dataclass

import yaml

from ..units import DPH, DPSH, UG

#: the file's four noise keys per convention: gyro white, gyro walk, accel white, accel walk
KEYS = {
    'kalibr': ('gyroscope_noise_density', 'gyroscope_random_walk',
               'accelerometer_noise_density', 'accelerometer_random_walk'),
    'vins': ('gyr_n', 'gyr_w', 'acc_n', 'acc_w'),
}
#: physical ranges (SI): outside them a value is almost certainly in the wrong unit
#: (deg instead of rad, a variance for a density, per-hour units)
RANGES = ((1e-7, 1e-1, 'rad/s/sqrt(Hz)'), (0.0, 1e-1, 'rad/s^2/sqrt(Hz)'),
          (1e-6, 1.0, 'm/s^2/sqrt(Hz)'), (0.0, 1.0, 'm/s^3/sqrt(Hz)'))
#: the model parameters a file sets (where they are not given)
SETS = ('gyro_arw_dpsh', 'gyro_bias_instability_dph', 'accel_vrw_ug_rthz', 'accel_bias_ug')


@dataclass(frozen=True)
class ImuNoise:
    """What an IMU noise file says, SI units.

    ``gyro_white`` rad/s/sqrt(Hz), ``gyro_walk`` rad/s^2/sqrt(Hz), ``accel_white``
    m/s^2/sqrt(Hz), ``accel_walk`` m/s^3/sqrt(Hz), ``rate_hz`` the file's ``update_rate``
    (None without one), ``convention`` ``kalibr``, ``openvins`` or ``vins``.
    """

    path: str
    convention: str
    gyro_white: float
    gyro_walk: float
    accel_white: float
    accel_walk: float
    rate_hz: float = None


class _Loader(yaml.SafeLoader):
    """A safe loader that reads OpenCV's tagged nodes (``!!opencv-matrix``) as plain ones."""


def _untagged(loader, _suffix, node):
    if isinstance(node, yaml.MappingNode):
        return loader.construct_mapping(node)
    if isinstance(node, yaml.SequenceNode):
        return loader.construct_sequence(node)
    return loader.construct_scalar(node)


_Loader.add_multi_constructor('tag:yaml.org,2002:', _untagged)
_Loader.add_multi_constructor('!', _untagged)


def _load(path):
    """Return the file's top-level mapping; ``ValueError`` with one line otherwise."""
    try:
        with open(path) as f:
            text = f.read()
    except OSError as exc:
        raise ValueError(f'imu_noise_file {path}: cannot open it ({exc.strerror})') from None
    # OpenCV writes "%YAML:1.0", which is not a YAML directive
    lines = text.splitlines()
    if lines and lines[0].startswith('%YAML:'):
        text = '\n'.join(lines[1:])
    try:
        data = yaml.load(text, Loader=_Loader)
    except yaml.YAMLError as exc:
        where = getattr(exc, 'problem_mark', None)
        at = f' at line {where.line + 1}' if where is not None else ''
        raise ValueError(f'imu_noise_file {path}: not valid YAML{at}: '
                         f'{getattr(exc, "problem", None) or exc}') from None
    if not isinstance(data, dict):
        raise ValueError(f'imu_noise_file {path}: not a YAML mapping of IMU noise keys')
    return data


def _entry(data, path):
    """Return ``(convention, mapping)`` of the IMU noise keys in ``data``."""
    if any(k in data for k in KEYS['kalibr']):
        return 'kalibr', data
    if any(k in data for k in KEYS['vins']):
        return 'vins', data
    imus = {k: v for k, v in data.items()
            if isinstance(v, dict) and any(x in v for x in KEYS['kalibr'])}
    if len(imus) == 1 or 'imu0' in imus:
        return 'openvins', imus.get('imu0', next(iter(imus.values())))
    if imus:
        raise ValueError(f'imu_noise_file {path}: several IMUs ({", ".join(sorted(imus))}) '
                         'and no imu0')
    found = ', '.join(sorted(map(str, data))[:8]) or 'none'
    raise ValueError(f'imu_noise_file {path}: no IMU noise keys (Kalibr '
                     'gyroscope_noise_density..., OpenVINS imu0: {...}, or VINS-Fusion '
                     f'gyr_n/gyr_w/acc_n/acc_w); its keys: {found}')


def _number(v):
    """Return ``v`` as a finite float, or None (a bool, text, a list are not numbers)."""
    if isinstance(v, bool):
        return None
    if isinstance(v, str):
        try:
            v = float(v)        # PyYAML reads "1e-4" (no dot) as text
        except ValueError:
            return None
    if not isinstance(v, (int, float)) or not math.isfinite(v):
        return None
    return float(v)


def read(path):
    """Read the IMU noise file at ``path``; return an :class:`ImuNoise`.

    Raises ``ValueError`` with one line for a file that cannot be opened, is not YAML,
    holds none of the conventions' keys, lacks one of the four noise keys, has a value that
    is not a number, or one outside its physical range (:data:`RANGES`: a gyro noise
    density above 1e-1 or below 1e-7 rad/s/sqrt(Hz) is almost certainly a unit mistake).
    """
    path = str(path)
    convention, entry = _entry(_load(path), path)
    names = KEYS['vins' if convention == 'vins' else 'kalibr']
    missing = [k for k in names if k not in entry]
    if missing:
        raise ValueError(f'imu_noise_file {path} ({convention}): missing '
                         f'{", ".join(missing)}')
    values = []
    for key, (lo, hi, unit) in zip(names, RANGES):
        v = _number(entry[key])
        if v is None:
            raise ValueError(f'imu_noise_file {path}: {key} = {entry[key]!r} is not a number')
        if not lo <= v <= hi:
            raise ValueError(f'imu_noise_file {path}: {key} = {v:g} {unit} is outside '
                             f'[{lo:g}, {hi:g}]: almost certainly a unit mistake (the file '
                             'is SI: rad, not deg; a density, not a variance)')
        values.append(v)
    rate = entry.get('update_rate')
    if rate is not None:
        rate = _number(rate)
        if rate is None or not 0.0 < rate <= 1e5:
            raise ValueError(f'imu_noise_file {path}: update_rate = {entry["update_rate"]!r} '
                             'is not a rate in Hz')
    return ImuNoise(path, convention, *values, rate_hz=rate)


def model_values(noise, gyro_bias_tau_s, accel_bias_tau_s, accel_turn_on_ug):
    """Return the model parameters (:data:`SETS`, their units) ``noise`` gives (module doc).

    ``gyro_bias_tau_s``, ``accel_bias_tau_s`` the correlation times set (s),
    ``accel_turn_on_ug`` the accelerometer bias set, taken as the turn-on part (micro-g).
    """
    walk_a = noise.accel_walk * math.sqrt(accel_bias_tau_s / 2.0) / UG
    return {'gyro_arw_dpsh': noise.gyro_white / DPSH,
            'gyro_bias_instability_dph':
                noise.gyro_walk * math.sqrt(gyro_bias_tau_s / 2.0) / DPH,
            'accel_vrw_ug_rthz': noise.accel_white / UG,
            'accel_bias_ug': math.hypot(accel_turn_on_ug, walk_a)}


def apply(values, given, defaults):
    """Fill ``values`` from its ``imu_noise_file``; return ``(values, summary)``.

    ``values`` the parameter values (a dict; a copy is returned), ``given`` the names set
    explicitly (they are kept), ``defaults`` name -> default for those absent from
    ``values``. ``summary`` says what was read and set, for the log and /diagnostics ('' when
    no file is set). Raises ``ValueError`` (one line) for a bad file (:func:`read`).
    """
    path = values.get('imu_noise_file', '')
    if not path:
        return dict(values), ''
    noise = read(path)

    def get(name):
        return values.get(name, defaults[name])

    derived = model_values(noise, get('gyro_bias_tau_s'), get('accel_bias_tau_s'),
                           get('accel_bias_ug'))
    out = dict(values)
    kept = [k for k in SETS if k in given]
    out.update({k: v for k, v in derived.items() if k not in given})
    return out, summary(noise, derived, kept)


def summary(noise, derived, kept=()):
    """Return one line: the file, what it holds, the model values it gives, those kept."""
    rate = f', update_rate {noise.rate_hz:g} Hz' if noise.rate_hz is not None else ''
    text = (f'imu_noise_file {noise.path} ({noise.convention}{rate}): gyro '
            f'{noise.gyro_white:.3g} rad/s/sqrt(Hz) -> gyro_arw_dpsh '
            f'{derived["gyro_arw_dpsh"]:.4g}, walk {noise.gyro_walk:.3g} rad/s^2/sqrt(Hz) '
            f'-> gyro_bias_instability_dph {derived["gyro_bias_instability_dph"]:.4g}; accel '
            f'{noise.accel_white:.3g} m/s^2/sqrt(Hz) -> accel_vrw_ug_rthz '
            f'{derived["accel_vrw_ug_rthz"]:.4g}, walk {noise.accel_walk:.3g} m/s^3/sqrt(Hz) '
            f'-> accel_bias_ug {derived["accel_bias_ug"]:.4g}')
    if kept:
        text += f'; given as parameters, kept: {", ".join(kept)}'
    return text
