"""Feed-forward commissioned on the measured drive: the acceleration feed-forward from the identified
inertia and the inertia coupling between axes.

Why these terms (the card's side: :mod:`cnc_twin.dsp.pid`). The drive closes a PI speed loop (gain
``kv`` [N/(m/s) | N m/(rad/s)], integral time ``tn``) on an inertia ``m``; its speed follows a
commanded speed through ``(kv s + kv / tn) / (m s^2 + kv s + kv / tn)``, whose exact inverse is
``1 + (m / kv) s . s tn / (1 + s tn)``. So::

    kaff         = m / kv      [s]    m identified on the drive's own signals
    aff_washout  = tn          [s]    the high-pass, where the drive's integral takes over
    coupling_j   = M_j / m     [-]    M_j: the force on this axis per unit of axis j's acceleration
                                      (a tilting head under an accelerating table), the mass
                                      matrix's entry as the CAD model (the MJCF) enters it: on the
                                      machine the head's bearing friction (3 N m at the output,
                                      5 at the motor) holds it against most of a drive run's
                                      accelerations, so a run cannot part the two

The inertia from each axis's rigid body, identified on its drive's own signals (two sines of speed
through the drive, :func:`~cnc_twin.studies.commissioning.identify_rigid_body`).

Why no symmetrising lag (``servo.ff_equivalent_time``): real controls delay the position loop's
command by the speed loop's equivalent time where they feed forward the speed alone, so that the
loop does not fight the lag the drive adds. With the inverse above the drive adds (almost) none:
what remains between the axes that interpolate together is what the circular tests' 45 deg
ellipse measures (:func:`~cnc_twin.studies.commission.matched_dynamics`: 0.01 - 0.06 ms on the
default machine), and a lag set per axis would draw that ellipse itself (v dT / 2: 37 um at
6 m/min for 0.75 ms), one set on all of them shrinks the circles (R T w^2 / kp: 6 um more on the
6 m/min circle for 1 ms, its RMS up from 4.6 to 5.0 um). The key stays for a drive whose speed loop is no PI.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from cnc_twin.core import units
from cnc_twin.core.axes import is_rotary
from cnc_twin.core.config import Scenario
from cnc_twin.studies.commissioning import RigidBody, entered_coupling

@dataclass
class FeedForward:
    """One axis's feed-forward in SI: ``kaff`` [s], ``washout`` [s], ``coupling`` per other axis [SI units of this axis's acceleration per the other's], ``inertia``
    the identified inertia [kg | kg m^2]."""

    axis: str
    inertia: float
    kaff: float
    washout: float
    coupling: dict[str, float] = field(default_factory=dict)

    def overrides(self) -> dict[str, object]:
        """The scenario overrides that set it, in the scenario's units (s, ms, mm or deg per mm or deg)."""
        a = self.axis
        own = units.position_factor(is_rotary(a))
        coupling = {other: round(value * units.position_factor(is_rotary(other)) / own, 5)
                    for other, value in self.coupling.items()}
        out: dict[str, object] = {f"servo.{a}.kaff": round(self.kaff, 6),
                                  f"servo.{a}.aff_washout": round(self.washout / units.MS, 3)}
        if coupling:
            out[f"servo.{a}.coupling"] = coupling
        return out

    def describe(self) -> str:
        """One line in the scenario's units."""
        o = self.overrides()
        a = self.axis
        unit = "kg m^2" if is_rotary(a) else "kg"
        coupling = o.get(f"servo.{a}.coupling") or {}
        text = f"inertia {self.inertia:.4g} {unit} -> kaff {self.kaff * 1e3:.3f} ms, high-pass {o[f'servo.{a}.aff_washout']:g} ms"
        if coupling:
            text += ", coupling " + " ".join(f"{k} {v:+.4g}" for k, v in coupling.items())
        return text


def feed_forward(scenario: Scenario, bodies: Mapping[str, RigidBody]) -> dict[str, FeedForward]:
    """The :class:`FeedForward` (module docstring) of each axis of ``bodies`` (its rigid body,
    identified on the drive's own signals, :func:`~cnc_twin.studies.commissioning.identify_rigid_body`)
    on ``scenario``'s machine, with the couplings among them."""
    out: dict[str, FeedForward] = {}
    for axis, body in bodies.items():
        drive = scenario.axis(axis).drive
        if drive is None:
            raise ValueError(f"{axis}: the feed-forward is set from a drive with loops of its own "
                             "(the parameter file's drive: ...); this axis has the MJCF's ideal velocity source")
        out[axis] = FeedForward(axis, body.inertia, body.inertia / drive.kp, drive.tn)
    for axis, forces in entered_coupling(scenario, list(out)).items():  # the CAD model's cross inertia
        for other, force in forces.items():  # over the identified inertia
            ratio = force / out[axis].inertia
            if abs(ratio) > 1e-9:
                out[axis].coupling[other] = ratio
    return out
