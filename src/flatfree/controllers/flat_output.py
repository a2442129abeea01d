"""The paper's two designs on flat outputs (Sections 2.3 and 3.3) for a user's own loop.

:class:`FlatOutputController` is to ``mfc-flat`` and ``flatness`` what
:class:`~flatfree.controllers.vehicle.NaturalOutputController` is to ``mfc-natural``: the
closed-loop engine's compiled kernel (:func:`~flatfree.controllers.vehicle.vehicle_step`)
behind ``reset()`` / ``step()``. Both track y1 = Vx (wheel torque) and y2 = lf m Vy - Iz r
(steer): with :class:`~flatfree.controllers.vehicle.MfcFlatSettings` two decoupled iPIs
(nu = 1, model-free: m, Iz, lf form y2), with
:class:`~flatfree.controllers.vehicle.FlatnessSettings` the flatness-based law on the linear
3DoF design model (:func:`~flatfree.controllers.flatness_control.flatness_step`). Both add, by
default, the outer path-following correction of the y2 reference (module docstring of
:mod:`flatfree.controllers.vehicle`): without it they track velocities only and drift off the
path within a lap. (:class:`~flatfree.controllers.flatness_control.FlatnessController` is
the paper's flatness law exactly, on a time-scheduled :class:`FlatReference`, without the
correction.)

The y2 reference and its derivative come from the 3DoF model along your path:
:func:`flatfree.tracks.reference_states_3dof` gives ``y2``, ``y2_dot`` (and the sideslip rate
for ``r_kin``) along a :func:`flatfree.make_reference` reference, read at the car's arc length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from flatfree._validate import real
from flatfree._warn import warn
from flatfree.actuators import ActuatorParams
from flatfree.controllers.flatness import SAFE_MARGIN, singular_speed
from flatfree.controllers.flatness_control import FST, FlatnessControlStatus, flatness_status
from flatfree.controllers.intelligent import (
    IntelligentStatus,
    intelligent_law_ran,
    intelligent_status,
)
from flatfree.controllers.vehicle import (
    _OUTER_HELD,
    _OUTER_SHIFT,
    CREF,
    MEAS,
    FlatnessSettings,
    MfcFlatSettings,
    VehicleControllerArrays,
    _OwnLoopShell,
    build_flatness,
    build_mfc,
)
from flatfree.models.bicycle3dof import Bicycle3DoFParams

__all__ = ["FlatOutputController", "FlatOutputStatus"]

# plain-int slots (an IntEnum member costs an attribute lookup and a conversion per use)
_M_VX, _M_VY, _M_R = int(MEAS.VX), int(MEAS.VY), int(MEAS.R)
_M_EY, _M_EPSI = int(MEAS.E_Y), int(MEAS.E_PSI)
_C_VX, _C_AX, _C_Y2, _C_Y2D = int(CREF.VX), int(CREF.AX), int(CREF.Y2), int(CREF.Y2_DOT)
_C_Y2DD = int(CREF.Y2_DDOT)
_C_EY, _C_EYD = int(CREF.EY), int(CREF.EY_DOT)
_C_G, _C_RKIN = int(CREF.Y2_PER_R), int(CREF.R_KIN)


@dataclass(frozen=True, slots=True)
class FlatOutputStatus:
    """Snapshot of a :class:`FlatOutputController` after its last step.

    Attributes
    ----------
    speed, lateral : IntelligentStatus or None
        The model-free design's iPIs (``None`` for the flatness law): on the speed (y = vx
        [m/s], u = wheel torque [N m]) and on y2 = lf m vy - Iz r (y [kg m^2/s], u = steer
        [rad]); the lateral ``error`` is ``y2 - y2_ref`` with the path correction's shift in
        ``y2_ref``, its ``f_hat`` the F of ``y2' = F + alpha delta`` [kg m^2/s^2].
    flatness : FlatnessControlStatus or None
        The flatness law's flags, errors (reference minus output, the paper's sign) and
        counters (``None`` for the model-free design).
    steer_held : bool
        The last steer is not the law's: the model-free design's window still filling (the
        start's steer held), a non-finite ``vy``, ``r`` or y2 reference, or a speed below
        ``steer_min_speed`` (the steer applied last held); for the flatness law any step but
        ``FCS.ok`` (a bad measurement or reference, or the fallback below the hand-over
        speed). True before the first step.
    y2_shift : float
        The path correction's shift of the y2 reference in the last step [kg m^2/s] (0
        without the correction or before the first step).
    correction_held : bool
        The last step held the shift of the step before (a non-finite input of the
        correction: ``e_y``, ``e_psi``, ``vx``, ...).
    """

    speed: IntelligentStatus | None
    lateral: IntelligentStatus | None
    flatness: FlatnessControlStatus | None
    steer_held: bool
    y2_shift: float
    correction_held: bool


class FlatOutputController(_OwnLoopShell):
    """The paper's designs on flat outputs (Sections 2.3, 3.3) for a user's own loop.

    ``reset()`` / ``step()`` over the same compiled kernel as the closed-loop engine's
    ``mfc-flat`` and ``flatness`` (module docstring), the design chosen by the settings' class.
    Call :meth:`step` once per control period ``dt``; hold its outputs until the next call
    (zero-order hold). One controller per loop (its state is updated in place); ``copy.copy``
    gives an independent controller in the same state.

    Parameters
    ----------
    dt : float
        Control period [s]. The model-free settings' windows count samples, tuned at 1 ms: at
        another period pass ``settings.for_period(dt)``, which keeps their durations.
    actuators : ActuatorParams
        Steer and torque limits; the iPIs' limits mirror them, and, unless told what was
        applied, the controller assumes that these actuators
        (:func:`flatfree.actuators.actuate_step`) applied its previous command (the iPIs'
        estimators and the flatness law's anti-windup must see the input applied).
    model : Bicycle3DoFParams
        The car's nominal design model (``Bicycle3DoFParams.from_vehicle(vehicle)``). The
        model-free design uses its ``m``, ``iz`` and ``lf`` (y2 = lf m vy - Iz r, the paper's
        design); the flatness law the whole model, its ``cf``, ``cr`` scaled by the settings'
        ``cf_scale``, ``cr_scale``. The path correction converts its yaw-rate correction to
        y2 with that model's steady ratio d y2 / d r
        (:func:`~flatfree.controllers.vehicle.y2_per_r`), unless :meth:`step` is given
        ``y2_per_r``. A model with a yaw index ``Iz / (m lf lr)`` below 1 has a singular speed
        (:func:`flatfree.controllers.flatness.singular_speed`; the dallara_av21 10.8 m/s)
        where the steer loses its effect on y2: the model-free design warns once at the first
        measured speed within 50 % of it (above ``steer_min_speed``), the flatness law hands
        over to its fallback there.
    settings : MfcFlatSettings or FlatnessSettings, optional
        Default ``MfcFlatSettings()`` (the model-free design as the engine's ``paper-mfc-flat``
        runs it at 1 kHz; ``alpha_lat`` scales with the car's ``-lf Cf`` times the window,
        :class:`~flatfree.controllers.vehicle.MfcFlatSettings`); ``FlatnessSettings()`` the
        flatness law as ``paper-flatness`` runs it, ``FlatnessSettings(cf_scale=0.3,
        cr_scale=0.3)`` as ``paper-mismatch``. ``path_correction = False`` is the paper's
        design exactly (velocities only).

    Examples
    --------
    >>> from flatfree import ActuatorParams, Bicycle3DoFParams, load_vehicle
    >>> car = load_vehicle("peugeot406")
    >>> ctrl = FlatOutputController(dt=0.001, actuators=ActuatorParams.from_vehicle(car),
    ...                             model=Bicycle3DoFParams.from_vehicle(car))
    >>> ctrl.reset()
    >>> torque, steer = ctrl.step(vx=20.0, vy=0.0, r=0.0, vx_ref=20.0, y2_ref=0.0,
    ...                           y2_ref_dot=0.0, e_y=0.01, e_psi=0.0)

    The flatness law (it needs ``y2_ref_ddot`` too):

    >>> from flatfree.controllers.vehicle import FlatnessSettings
    >>> law = FlatOutputController(dt=0.001, actuators=ActuatorParams.from_vehicle(car),
    ...                            model=Bicycle3DoFParams.from_vehicle(car),
    ...                            settings=FlatnessSettings())
    >>> torque, steer = law.step(vx=20.0, vy=0.0, r=0.0, vx_ref=20.0, y2_ref=0.0,
    ...                          y2_ref_dot=0.0, y2_ref_ddot=0.0, e_y=0.01, e_psi=0.0)

    References
    ----------
    [paper] Sections 2.3 and 3.3; NOTES.md; :mod:`flatfree.controllers.vehicle` (the outer
    correction, the sign of ``alpha_lat``).
    """

    __slots__ = ("_model", "_lfm", "_g0", "_crl", "_flatness", "_v_warn", "_warned")

    _SETTINGS = (MfcFlatSettings, FlatnessSettings)

    def __init__(self, *, dt: float, actuators: ActuatorParams, model: Bicycle3DoFParams,
                 settings: MfcFlatSettings | FlatnessSettings | None = None) -> None:
        if not isinstance(model, Bicycle3DoFParams):
            raise ValueError(f"model = {model!r:.60}: expected flatfree.Bicycle3DoFParams "
                             "(e.g. Bicycle3DoFParams.from_vehicle(vehicle))")
        self._model = model
        self._flatness = isinstance(settings, FlatnessSettings)
        # y2_per_r(design, vx) = (lf m lr - Iz) - (lf m vx)^2 / (Cr L), in the same
        # operations; the flatness law's design model has the settings' Cr
        cr = settings.cr_scale * model.cr if self._flatness else model.cr
        self._lfm = model.lf * model.m
        self._g0 = self._lfm * model.lr - model.iz
        self._crl = cr * (model.lf + model.lr)
        # the model-free design near the design model's singular speed (the flatness law hands
        # over there): warned once, at the first measured speed within SAFE_MARGIN of it
        # (-inf: never; 0 let a reversing flatness law read a steer_min_speed it has not)
        v_star = singular_speed(model)
        self._v_warn = (-math.inf if v_star is None or self._flatness
                        else (1.0 + SAFE_MARGIN) * v_star)
        self._warned = False
        super().__init__(dt=dt, actuators=actuators, settings=settings)

    @property
    def settings(self) -> MfcFlatSettings | FlatnessSettings:
        """The controller's settings."""
        return self._settings

    @property
    def model(self) -> Bicycle3DoFParams:
        """The nominal design model."""
        return self._model

    def reset(self, *, steer0: float = 0.0, torque0: float = 0.0) -> None:
        """Fresh estimators (or integrals) and path-correction integral; ``steer0`` [rad] and
        ``torque0`` [N m] are the actuators' positions: the model-free design holds them until
        its estimator windows are full (``window_lon`` / ``window_lat`` samples, 50 each by
        default), the flatness law returns them from a step that holds before any law step
        and starts its anti-windup's comparison from them. Each within the actuators' range
        (``ValueError`` otherwise)."""
        super().reset(steer0=steer0, torque0=torque0)

    def _build(self, steer0: float, torque0: float) -> VehicleControllerArrays:
        m = self._model
        if self._flatness:
            z = build_flatness(self._settings, dt=self._dt, model=m)
            z.s_lon[int(FST.TW)] = torque0
            z.s_lon[int(FST.DELTA)] = steer0
            return z
        return build_mfc("mfc-flat", self._settings, dt=self._dt, actuators=self._act,
                         mass=m.m, iz=m.iz, lf=m.lf, steer0=steer0, torque0=torque0)

    def step(self, *, vx: float, vy: float, r: float, vx_ref: float, y2_ref: float,
             y2_ref_dot: float, ax_ref: float = 0.0, y2_ref_ddot: float | None = None,
             e_y: float | None = None,
             e_psi: float | None = None, e_y_ref: float = 0.0, e_y_ref_dot: float = 0.0,
             r_kin: float = 0.0, y2_per_r: float | None = None,
             applied_torque: float | None = None,
             applied_steer: float | None = None) -> tuple[float, float]:
        """One control step: returns (wheel torque [N m], road-wheel steer [rad]).

        A bumpless start (model-free): until its estimator's window is full (the first
        ``window - 1`` steps, 49 ms at the default settings) each loop gives the
        :meth:`reset`'s ``torque0`` and ``steer0``; the flatness law has no window and
        applies its law from the first step. Lost samples: a non-finite ``vy`` or ``r`` holds
        the steer applied last (the window keeps its time base), a non-finite ``vx`` the
        model-free torque; the flatness law holds both outputs on any of the three. A
        non-finite ``e_y``, ``e_psi``, ``vx``, ``vx_ref``, ``y2_per_r``, ``r_kin`` or lateral
        reference holds the path correction's last shift of the y2 reference (its integral
        holds too; ``status.correction_held``). At a standstill: the model-free design holds
        the steer below ``settings.steer_min_speed`` (1 m/s), the flatness law hands over
        below its hand-over speed, 0 m/s and reversing included, to its fallback (steer
        held, P on the speed;
        :class:`~flatfree.controllers.flatness_control.FlatnessControlParams`). The torque
        and the steer returned are within the actuators' ranges.

        Conventions (ISO 8855): body axes at the CoG, x forward, y left, z up; the yaw rate,
        the steer and ``e_y`` positive to the left; the torque is the sum at the wheels, > 0
        driving.

        Parameters
        ----------
        vx, vy : float
            Measured velocity of the CoG in body axes [m/s].
        r : float
            Measured yaw rate [rad/s].
        vx_ref, ax_ref : float
            Speed reference [m/s] and its time derivative [m/s^2] (the speed iPI's
            feedforward: without it the speed lags the profile).
        y2_ref, y2_ref_dot : float
            Reference of y2 = lf m vy - Iz r [kg m^2/s] and its time derivative
            [kg m^2/s^2], from the 3DoF model along the path (module docstring; the
            flatness law's with its own, scaled, design model).
        y2_ref_ddot : float, optional
            Its second derivative [kg m^2/s^3]: the flatness law's feedforward, required
            with :class:`FlatnessSettings` (``ValueError`` when left out), not read by the
            model-free design (nu = 1).
        e_y, e_psi : float, optional
            Measured lateral deviation from the path [m] and heading error (yaw minus the
            path's heading) [rad]. Required while ``settings.path_correction`` is on
            (``ValueError`` naming them when left out; NaN for a lost sample), not read
            (but checked) when it is off.
        e_y_ref, e_y_ref_dot : float
            Lateral-deviation reference and its derivative (0: follow the path).
        r_kin : float
            Minus the reference's sideslip rate, ``-beta_ref'`` [rad/s]
            (``sideslip_feedforward``; 0 when unknown: a little more lateral error).
        y2_per_r : float, optional
            The correction's d y2 / d r [kg m^2/s per rad/s]; ``None``: the design model's
            steady ratio at ``vx_ref`` (:func:`~flatfree.controllers.vehicle.y2_per_r`,
            ``lf m lr - Iz - (lf m vx)^2 / (Cr L)``: negative above the design model's
            singular speed, :func:`flatfree.controllers.flatness.singular_speed`, where it
            passes through 0 and the correction vanishes; a car with a yaw index
            ``Iz / (m lf lr)`` below 1 has one, the dallara_av21 at 10.8 m/s, the peugeot406 at
            0.58 m/s). A value of the wrong sign turns the correction away from the path.
        applied_torque, applied_steer : float, optional
            What the actuators applied over the last period, if known; ``None`` or a
            non-finite value: the previous command through the model of ``actuators``.

        Raises
        ------
        ValueError
            An argument that is not one real number (naming it), ``e_y`` / ``e_psi`` left out
            with the path correction on, ``y2_ref_ddot`` left out for the flatness law, or a
            torque or steer that came out non-finite (the arithmetic overflowed); the
            controller is then reset at its last finite commands.
        """
        # the common path (floats) costs one type test per argument (_shell docstring)
        vx = vx if isinstance(vx, float) else real("vx", vx, "m/s")
        vy = vy if isinstance(vy, float) else real("vy", vy, "m/s")
        r = r if isinstance(r, float) else real("r", r, "rad/s")
        vx_ref = vx_ref if isinstance(vx_ref, float) else real("vx_ref", vx_ref, "m/s")
        ax_ref = ax_ref if isinstance(ax_ref, float) else real("ax_ref", ax_ref, "m/s^2")
        y2_ref = y2_ref if isinstance(y2_ref, float) else real("y2_ref", y2_ref, "kg m^2/s")
        if not isinstance(y2_ref_dot, float):
            y2_ref_dot = real("y2_ref_dot", y2_ref_dot, "kg m^2/s^2")
        c = self._ref
        if self._flatness:
            if y2_ref_ddot is None:
                raise ValueError("y2_ref_ddot = None: required with FlatnessSettings (the "
                                 "flatness law's feedforward, kg m^2/s^3)")
            if not isinstance(y2_ref_ddot, float):
                y2_ref_ddot = real("y2_ref_ddot", y2_ref_ddot, "kg m^2/s^3")
            c[_C_Y2DD] = y2_ref_ddot
        if e_y is not None and not isinstance(e_y, float):
            e_y = real("e_y", e_y, "m")
        if e_psi is not None and not isinstance(e_psi, float):
            e_psi = real("e_psi", e_psi, "rad")
        if self._settings.path_correction:
            if e_y is None or e_psi is None:
                missing = " and ".join(k for k, v in (("e_y", e_y), ("e_psi", e_psi))
                                       if v is None)
                raise ValueError(
                    f"{missing} = None: required with settings.path_correction = True (the "
                    "outer loop steers back to the path from them; NaN for a lost sample), "
                    "or use MfcFlatSettings(path_correction=False), the paper's design")
            if not isinstance(e_y_ref, float):
                e_y_ref = real("e_y_ref", e_y_ref, "m")
            if not isinstance(e_y_ref_dot, float):
                e_y_ref_dot = real("e_y_ref_dot", e_y_ref_dot, "m/s")
            r_kin = r_kin if isinstance(r_kin, float) else real("r_kin", r_kin, "rad/s")
            if y2_per_r is None:
                g = self._lfm * vx_ref
                y2_per_r = self._g0 - g * g / self._crl
            elif not isinstance(y2_per_r, float):
                y2_per_r = real("y2_per_r", y2_per_r, "kg m^2/s / (rad/s)")
            c[_C_EY] = e_y_ref
            c[_C_EYD] = e_y_ref_dot
            c[_C_G] = y2_per_r
            c[_C_RKIN] = r_kin
        if vx < self._v_warn and not self._warned and vx >= self._settings.steer_min_speed:
            self._warn_singular(vx)
        a_tw, a_delta = self._applied(vx, applied_torque, applied_steer)
        m = self._meas
        m[_M_VX] = vx
        m[_M_VY] = vy
        m[_M_R] = r
        m[_M_EY] = math.nan if e_y is None else e_y
        m[_M_EPSI] = math.nan if e_psi is None else e_psi
        c[_C_VX] = vx_ref
        c[_C_AX] = ax_ref
        c[_C_Y2] = y2_ref
        c[_C_Y2D] = y2_ref_dot
        return self._step_kernel(vx, a_tw, a_delta, lambda: dict(
            vx=vx, vy=vy, r=r, vx_ref=vx_ref, y2_ref=y2_ref, y2_ref_dot=y2_ref_dot,
            ax_ref=ax_ref, y2_ref_ddot=y2_ref_ddot, e_y=e_y, e_psi=e_psi, e_y_ref=e_y_ref,
            e_y_ref_dot=e_y_ref_dot, r_kin=r_kin, y2_per_r=y2_per_r,
            applied_torque=applied_torque, applied_steer=applied_steer))

    def _warn_singular(self, vx: float) -> None:
        m = self._model
        self._warned = True
        warn(f"FlatOutputController (mfc-flat): vx = {vx:.3g} m/s is within "
             f"{SAFE_MARGIN:.0%} of the design model's singular speed "
             f"{self._v_warn / (1.0 + SAFE_MARGIN):.3g} m/s (yaw index Iz / (m lf lr) = "
             f"{m.iz / (m.m * m.lf * m.lr):.3f} < 1): there the steer has little effect on "
             "y2 = lf m vy - Iz r, and the opposite one below it; the lateral loop fails near "
             "that speed (the flatness law hands over to its fallback there)", UserWarning)

    @property
    def status(self) -> FlatOutputStatus:
        """The loops' counters, flags and estimates after the last step
        (:class:`FlatOutputStatus`)."""
        z = self._arrays
        shift = float(z.coef[_OUTER_SHIFT])
        held = bool(z.coef[_OUTER_HELD])
        if self._flatness:
            law = flatness_status(z.s_lon)
            return FlatOutputStatus(speed=None, lateral=None, flatness=law,
                                    steer_held=law.code != 0 or z.s_lon[int(FST.LAW)] == 0.0,
                                    y2_shift=shift, correction_held=held)
        # (False before a step: NaN)
        below = self._vx_prev < self._settings.steer_min_speed
        return FlatOutputStatus(
            speed=intelligent_status(z.p_lon, z.s_lon),
            lateral=intelligent_status(z.p_lat, z.s_lat), flatness=None,
            steer_held=below or not intelligent_law_ran(z.p_lat, z.s_lat), y2_shift=shift,
            correction_held=held)
