r"""
Stance from the joint efforts: :class:`EffortContacts` (``contact_source: effort``).

A robot without contact sensors publishes its joint states with efforts. The leg equations
of motion :math:`\tau_k = b_k - J_k^T f_k` (seed eq. 1; :mod:`awp_ros.wrench.contact_forces`)
give each foot's measured contact force

.. math:: f_k = J_k^{-T} (b_k - \tau_k) \quad [N]

(least squares for legs without 3 independent joints), with :math:`J_k` the foot's
translational Jacobian (LOCAL_WORLD_ALIGNED, world axes) and :math:`b_k` its leg's rows of
``rnea(q, v, a)`` for the motion the evaluation uses. Its normal component
:math:`f_{n,k} = n \cdot f_k` (``n`` the config's ``contact_normal``, world axes) decides the
stance with hysteresis: a swing foot touches down when :math:`f_{n,k} >` ``on_n``, a stance
foot lifts off when :math:`f_{n,k} <` ``off_n`` (``off_n <= on_n``), so that force noise
around one threshold does not make the stance chatter. A foot starts in swing.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from awp_ros.errors import InputError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.robot.state import resolve_state, RobotState

__all__ = ['EffortContacts']


class EffortContacts:
    """
    Decide the stance feet from measured normal forces, with hysteresis (module docstring).

    :param evaluator: the evaluator of the robot (its model and config).
    :param on_n: touch-down threshold on the normal force [N].
    :param off_n: lift-off threshold [N], ``<= on_n``.
    :ivar normal_forces: (K,) the last measured normal forces of every foot, config order [N].
    :ivar in_contact: (K,) the current stance flags, config order.
    """

    def __init__(self, evaluator: FeasibilityEvaluator, *, on_n: float, off_n: float) -> None:
        self.evaluator = evaluator
        self.on_n = float(on_n)
        self.off_n = float(off_n)
        feet = evaluator.config.feet
        self.feet = tuple(feet)
        self.normal = np.asarray(evaluator.config.unit_normal, dtype=float)
        self.in_contact = np.zeros(len(feet), dtype=bool)
        self.normal_forces = np.full(len(feet), np.nan)
        legs = evaluator.model.legs
        self._three = all(len(legs[f].joints) == 3 for f in feet)
        self._tau_idx = [legs[f].v_idx - 6 for f in feet]

    def update(self, state: RobotState) -> list[str]:
        """
        Return the stance feet (config order) for a state with joint efforts.

        :param state: the state to evaluate (positions, efforts, and the motion when
            measured); its ``stance`` is ignored.
        :raises InputError: the state has no efforts, or an invalid value.
        """
        if state.joint_efforts is None:
            raise InputError("contact_source is 'effort' but joint_states carry no efforts "
                             '(one per joint name): the stance cannot be measured')
        model = self.evaluator.model
        s = resolve_state(replace(state, stance=list(self.feet), normals={},
                                  friction_coefficients={}),
                          model.joint_names, self.feet)
        kin = model.kinematics(s.q, self.feet, quaternion=s.quaternion, v=s.v, a=s.a)
        tau = s.tau
        if self._three:
            JT = np.swapaxes(np.array(kin.J), 1, 2)                       # (K, 3, 3)
            rhs = np.array(kin.bias) - np.array([tau[i] for i in self._tau_idx])
            try:
                f = np.linalg.solve(JT, rhs[:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:
                f = np.array([np.linalg.lstsq(a, b, rcond=None)[0] for a, b in zip(JT, rhs)])
        else:
            f = np.array([np.linalg.lstsq(J.T, b - tau[i], rcond=None)[0]
                          for J, b, i in zip(kin.J, kin.bias, self._tau_idx)])
        fn = f @ self.normal
        self.normal_forces = fn
        self.in_contact = np.where(self.in_contact, fn >= self.off_n, fn > self.on_n)
        return [foot for foot, c in zip(self.feet, self.in_contact.tolist()) if c]

    def reset(self) -> None:
        """Put every foot in swing (a new model, or stamps that went back)."""
        self.in_contact[:] = False
