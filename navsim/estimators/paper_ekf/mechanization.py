"""The mechanization of seed 003's filter: the right-hand side of (7)-(8) with the observer (13).

With ``C = D(alpha, beta, gamma) B^T`` (ENU to body), ``B = D(-phi, lambda + Omega t, 0)``
and the body rate omega, specific force f (inputs, bias states subtracted)::

    [alpha', beta', gamma'] = Phi(alpha, gamma) omega                      (7), corrected
    phi' = V_Y / (R_N + h)                                                  (7)
    V_Y' = f_N + acc_N,   acc_N = -cor k V_Y - m V_Y^2 / (R_N + h) + g_N     (7)
    V_X' = f_E + acc_E,   acc_E = cor V_Y - (2 Omega cos phi + k V_Y / (R_E + h)) m V_Y   (12)
    cor = 2 Omega sin phi + k V_Y tan(phi) / (R_E + h)

(``g_N = -Omega^2 r cos phi sin phi`` on the sphere, printed with ``+``; 0 on the
ellipsoid, whose normal gravity has no north component). The track constraint ``V_X = k
V_Y`` differentiated, (10)-(11), and (12) give the accelerometer observer (13): with ``u =
e - k n`` in body axes (``u_b = C u_n``, ``u_b,x = c11 - k c12``)::

    Z_ax - H_a = (f_E - k f_N - G) / u_b,x,   G = k acc_N + k_phi V_Y^2 / (R_N + h) - acc_E

* ``_make_stage(sin, cos, sqrt, scalars)`` -> ``stage(a, b, g, phi, V, t, wx, wy, wz, fx,
  fy, fz) -> (alpha', beta', gamma', phi', V_Y', Z_ax - H_a)``: the one Python form of these
  equations (built with :mod:`math`, and with :mod:`cmath` for the complex step in phi).
* ``_make_fused()`` -> ``fused(Y, w, f, t)``: the stage values together with the
  coefficients of the Riccati equation of (14) in one scalar pass: the state-dependent
  entries of ``A = dF/dY``, ``dH_a/dY`` (negated), the kinematic block of Q = F1 D_xi
  F1^T, the correlation F1 D_A H_w^T (its V_Y entry) and ``sigma^2 = H_w D_a H_w^T``. The
  stage values are the expressions of ``stage`` (the same numbers); the phi-derivatives
  are analytic on the sphere (chain rule through lambda(phi), h(phi), the radii and psi =
  lambda + Omega t) and by the complex step of ``stage`` on the ellipsoid (Martins et al.
  2003, step :data:`~navsim.estimators.paper_ekf.numerics.CSTEP`).

The compiled engine (:mod:`~navsim.estimators.paper_ekf.kernel`) has the same expressions
in numba's subset (arrays for the constants, ``np.sin`` so that the stage is complex-safe);
the tests hold the two to each other.

References: [003] eqs. (7), (10)-(13), Appendix 2; [4] Martins J.R.R.A., Sturdza P.,
Alonso J.J., ACM TOMS 29 (2003) 245-262.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Sequence

from .numerics import CSTEP
from .state import StateModel

__all__ = ["Mechanization"]


class Mechanization(StateModel):
    """(7)-(8) and (13): the stage function and the one-pass coefficients (a layer of :class:`PaperEkf`)."""

    _stage: Callable[..., tuple]
    _stage_c: Callable[..., tuple]
    _fused: Callable[..., tuple]

    def _make_stage(self, sin: Callable[[Any], Any], cos: Callable[[Any], Any], sqrt: Callable[[Any], Any],
                    track_scalars: Callable[[Any], tuple[Any, ...]]) -> Callable[..., tuple[Any, ...]]:
        """The right-hand side of (14) without the gain: F(Y) and the innovation (Z_ax - H_a).

        Returns ``stage(a, b, g, phi, V, t, wx, wy, wz, fx, fy, fz) -> (alpha', beta',
        gamma', phi', V_Y', innov)`` with ``innov = (u_b . f - G) / u_b,x`` = Z_ax - H_a.
        Complex-safe when built with cmath functions (complex step in phi).
        """
        om = self._omega
        two_om = 2.0 * om
        om2 = om * om
        sphere = self._sphere
        a_e, e2 = self._a, self._e2
        cent = self._cent
        printed_kin = self._printed_kin

        def stage(a: Any, b: Any, g: Any, phi: Any, V: Any, t: Any, wx: Any, wy: Any, wz: Any, fx: Any, fy: Any,
                  fz: Any) -> tuple[Any, ...]:
            sa = sin(a)
            ca = cos(a)
            sb = sin(b)
            cb = cos(b)
            sg = sin(g)
            cg = cos(g)
            p = sg * wx + cg * wy
            q = cg * wx - sg * wy
            if printed_kin:  # (1) printed Phi(beta, gamma)
                da, db, dg = p / cb, q, p * sb / cb + wz
            else:  # Phi(alpha, gamma), the kinematics of D (Appendix 1)
                da, db, dg = q, p / ca, p * sa / ca + wz
            # D of Appendix 1
            d00 = sb * sa * sg + cb * cg
            d01 = ca * sg
            d02 = cb * sa * sg - sb * cg
            d10 = sb * sa * cg - cb * sg
            d11 = ca * cg
            d12 = cb * sa * cg + sb * sg
            # f in the inertial (paper) axes: D^T f_b
            fp0 = d00 * fx + d10 * fy + sb * ca * fz
            fp1 = d01 * fx + d11 * fy - sa * fz
            fp2 = d02 * fx + d12 * fy + cb * ca * fz
            lam, dlam, ddlam, hh, dh = track_scalars(phi)
            sp = sin(phi)
            cp = cos(phi)
            psi = lam + om * t
            ss = sin(psi)
            cs = cos(psi)
            if sphere:
                rn = re = a_e + hh
                k = dlam * cp  # V_X = lambda' cos(phi) V_Y
                kphi = ddlam * cp - dlam * sp
                gn = cent * om2 * rn * cp * sp
            else:
                w = 1.0 - e2 * sp * sp
                r_e = a_e / sqrt(w)
                r_n = r_e * (1.0 - e2) / w
                rn = r_n + hh
                re = r_e + hh
                dre = r_e * e2 * sp * cp / w + dh
                drn = 3.0 * r_n * e2 * sp * cp / w + dh
                ratio = re / rn
                k = dlam * cp * ratio
                kphi = (ddlam * cp - dlam * sp) * ratio + dlam * cp * (dre - ratio * drn) / rn
                gn = 0.0
            m = dh / rn
            kv = k * V
            cor = two_om * sp + kv * sp / (cp * re)  # 2 Omega sin(phi) + V_X tan(phi) / (r + h)
            # (7): V_Y' = f_N + acc_n
            acc_n = -cor * kv - m * V * V / rn + gn
            # (12): V_X' = f_E + acc_e
            acc_e = cor * V - (two_om * cp + kv / re) * m * V
            # (10)-(12): f_E - k f_N = G
            gterm = k * acc_n + kphi * V * V / rn - acc_e
            f_n = cp * fp1 - sp * (ss * fp0 + cs * fp2)
            f_e = cs * fp0 - ss * fp2
            # u = e - k n in paper axes; u_b,x = (D u)_x = c11 - k c12
            w0 = d00 * (cs + k * sp * ss) - d01 * k * cp + d02 * (k * sp * cs - ss)
            return da, db, dg, V / rn, f_n + acc_n, (f_e - k * f_n - gterm) / w0  # (13): Z_ax - H_a

        return stage

    def _make_fused(self) -> Callable[..., tuple[Any, ...]]:
        """The fast form of :meth:`_coefficients` (same quantities, one scalar pass).

        Returns ``fused(Y, w, f, t) -> (first, a_dyn, hneg, q_dyn, s4, sig2)``: ``first``
        the stage values of :meth:`_make_stage` (the same expressions, so the same numbers),
        ``a_dyn`` the state-dependent entries of A = dF/dY in the order of ``self._a_pos``,
        ``hneg`` = d(Z_ax - H_a)/dY (n,), ``q_dyn`` the kinematic 3 x 3 block of Q (upper
        triangle, row by row) and Q_VV, ``s4`` the V_Y entry of the correlation F1 D_A H_w^T
        (its only non-zero entry), ``sig2`` = H_w D_a H_w^T. The stage values and their
        angle and V_Y derivatives share the trigonometry; on the sphere the phi-derivatives
        are analytic (chain rule through lambda(phi), h(phi), the radii and psi = lambda +
        Omega t) instead of a second, complex-step evaluation of the stage; on the ellipsoid
        the complex step is kept. :meth:`_coefficients` stays the reference (tests).
        """
        om = self._omega
        two_om = 2.0 * om
        om2 = om * om
        sphere = self._sphere
        a_e, e2 = self._a, self._e2
        cent = self._cent
        printed_kin = self._printed_kin
        n = self.n_states
        scal3 = self.track_functions.scalars3
        scal = self.track_functions.scalars
        stage_c = self._stage_c
        kphi_c = self._kphi_c
        sin, cos, sqrt = math.sin, math.cos, math.sqrt
        biases = self._biases
        ia, ig = self._i_ba, self._i_bg
        zeros = [0.0] * n
        obj = self

        def fused(Y: Sequence[float], w: Sequence[float], f: Sequence[float], t: float) -> tuple[Any, ...]:
            a, b, g, phi, V = Y[0], Y[1], Y[2], Y[3], Y[4]
            wx, wy, wz = w
            fx, fy, fz = f
            if biases:
                fx, fy, fz = fx - Y[ia], fy - Y[ia + 1], fz - Y[ia + 2]
                wx, wy, wz = wx - Y[ig], wy - Y[ig + 1], wz - Y[ig + 2]
            # ---- the stage (expressions as in _make_stage)
            sa = sin(a)
            ca = cos(a)
            sb = sin(b)
            cb = cos(b)
            sg = sin(g)
            cg = cos(g)
            p = sg * wx + cg * wy
            q = cg * wx - sg * wy
            if printed_kin:
                da, db, dg = p / cb, q, p * sb / cb + wz
            else:
                da, db, dg = q, p / ca, p * sa / ca + wz
            d00 = sb * sa * sg + cb * cg
            d01 = ca * sg
            d02 = cb * sa * sg - sb * cg
            d10 = sb * sa * cg - cb * sg
            d11 = ca * cg
            d12 = cb * sa * cg + sb * sg
            d20 = sb * ca
            d22 = cb * ca
            fp0 = d00 * fx + d10 * fy + sb * ca * fz
            fp1 = d01 * fx + d11 * fy - sa * fz
            fp2 = d02 * fx + d12 * fy + cb * ca * fz
            if sphere:
                lam, dlam, ddlam, dddlam, hh, dh, ddh = scal3(phi)
            else:
                lam, dlam, ddlam, hh, dh = scal(phi)
            sp = sin(phi)
            cp = cos(phi)
            psi = lam + om * t
            ss = sin(psi)
            cs = cos(psi)
            if sphere:
                rn = re = a_e + hh
                k = dlam * cp
                kphi = ddlam * cp - dlam * sp
                gn = cent * om2 * rn * cp * sp
            else:
                w_ = 1.0 - e2 * sp * sp
                r_e = a_e / sqrt(w_)
                r_n = r_e * (1.0 - e2) / w_
                rn = r_n + hh
                re = r_e + hh
                dre = r_e * e2 * sp * cp / w_ + dh
                drn = 3.0 * r_n * e2 * sp * cp / w_ + dh
                ratio = re / rn
                k = dlam * cp * ratio
                kphi = (ddlam * cp - dlam * sp) * ratio + dlam * cp * (dre - ratio * drn) / rn
                gn = 0.0
            m = dh / rn
            kv = k * V
            cor = two_om * sp + kv * sp / (cp * re)
            acc_n = -cor * kv - m * V * V / rn + gn
            acc_e = cor * V - (two_om * cp + kv / re) * m * V
            gterm = k * acc_n + kphi * V * V / rn - acc_e
            f_n = cp * fp1 - sp * (ss * fp0 + cs * fp2)
            f_e = cs * fp0 - ss * fp2
            w0s = d00 * (cs + k * sp * ss) - d01 * k * cp + d02 * (k * sp * cs - ss)
            innov = (f_e - k * f_n - gterm) / w0s
            first = (da, db, dg, V / rn, f_n + acc_n, innov)
            # ---- Jacobian (as in _coefficients)
            n_p0, n_p2 = -ss * sp, -cs * sp
            u_p0, u_p1, u_p2 = cs - k * n_p0, -k * cp, -ss - k * n_p2
            n_b0 = d00 * n_p0 + d01 * cp + d02 * n_p2
            n_b1 = d10 * n_p0 + d11 * cp + d12 * n_p2
            n_b2 = d20 * n_p0 - sa * cp + d22 * n_p2
            w0 = d00 * u_p0 + d01 * u_p1 + d02 * u_p2
            u_b1 = d10 * u_p0 + d11 * u_p1 + d12 * u_p2
            u_b2 = d20 * u_p0 - sa * u_p1 + d22 * u_p2
            y = innov * w0
            hneg = list(zeros)
            # f x n_b and f x u_b
            zn0, zn1, zn2 = fy * n_b2 - fz * n_b1, fz * n_b0 - fx * n_b2, fx * n_b1 - fy * n_b0
            zu0, zu1, zu2 = fy * u_b2 - fz * u_b1, fz * w0 - fx * u_b2, fx * u_b1 - fy * w0
            ww = w0 * w0
            # axes (cg, -sg, 0), (sg ca, cg ca, -sa), (0, 0, 1); dw0 = -(ax1 u_b2 - ax2 u_b1)
            a40 = cg * zn0 - sg * zn1
            hneg[0] = ((cg * zu0 - sg * zu1) * w0 - y * (sg * u_b2)) / ww
            sgca, cgca = sg * ca, cg * ca
            a41 = sgca * zn0 + cgca * zn1 - sa * zn2
            hneg[1] = ((sgca * zu0 + cgca * zu1 - sa * zu2) * w0 - y * (-(cgca * u_b2 + sa * u_b1))) / ww
            a42 = zn2
            hneg[2] = (zu2 * w0 - y * u_b1) / ww
            # kinematics rows
            if printed_kin:
                tb = sb / cb
                kin_a = (p * sb / (cb * cb), q / cb, -p, p / (cb * cb), q * tb)
                kin = ((sg / cb, cg / cb, 0.0), (cg, -sg, 0.0), (sg * tb, cg * tb, 1.0))
            else:
                ta = sa / ca
                kin_a = (-p, p * sa / (ca * ca), q / ca, p / (ca * ca), q * ta)
                kin = ((cg, -sg, 0.0), (sg / ca, cg / ca, 0.0), (sg * ta, cg * ta, 1.0))
            # ---- phi derivatives
            if sphere:
                rn2 = rn * rn
                a33 = -V * dh / rn2
                kphi_p = dddlam * cp - 2.0 * ddlam * sp - dlam * cp
                gn_p = cent * om2 * (dh * cp * sp + rn * (cp * cp - sp * sp))
                m_p = ddh / rn - dh * dh / rn2
                tphi = sp / (cp * rn)
                tphi_p = 1.0 / (cp * cp * rn) - sp * dh / (cp * rn2)
                cor_p = two_om * cp + V * (kphi * tphi + k * tphi_p)
                acc_n_p = -V * (cor_p * k + cor * kphi) - V * V * (m_p / rn - m * dh / rn2) + gn_p
                acc_e_p = cor_p * V - ((-two_om * sp + V * (kphi / rn - k * dh / rn2)) * m
                                       + (two_om * cp + kv / rn) * m_p) * V
                gterm_p = kphi * acc_n + k * acc_n_p + V * V * (kphi_p / rn - kphi * dh / rn2) - acc_e_p
                xs = ss * fp0 + cs * fp2
                f_n_p = -sp * fp1 - cp * xs - sp * dlam * f_e
                f_e_p = -dlam * xs
                w0s_p = (d00 * (-ss * dlam + kphi * sp * ss + k * cp * ss + k * sp * cs * dlam)
                         - d01 * (kphi * cp - k * sp)
                         + d02 * (kphi * sp * cs + k * cp * cs - k * sp * ss * dlam - cs * dlam))
                a43 = f_n_p + acc_n_p
                hneg[3] = (f_e_p - kphi * f_n - k * f_n_p - gterm_p - innov * w0s_p) / w0s
            else:
                cplx = stage_c(a, b, g, complex(phi, CSTEP), V, t, wx, wy, wz, fx, fy, fz)
                a33 = cplx[3].imag / CSTEP
                a43 = cplx[4].imag / CSTEP
                hneg[3] = cplx[5].imag / CSTEP
                kphi = float(kphi_c(phi))
            # ---- V_Y derivatives
            cor2 = two_om * sp + 2.0 * kv * sp / (cp * re)
            acc_n_v = -cor2 * k - 2.0 * m * V / rn
            acc_e_v = cor2 - (two_om * cp + 2.0 * kv / re) * m
            hneg[4] = -(k * acc_n_v + 2.0 * kphi * V / rn - acc_e_v) / w0
            a_dyn = [*kin_a, a33, 1.0 / rn, a40, a41, a42, a43, acc_n_v]
            # ---- process noise, correlation, measurement intensity
            qd, qa = obj._qd, obj._qa
            k0, k1, k2 = kin
            q_dyn = [qd * (k0[0] * k0[0] + k0[1] * k0[1] + k0[2] * k0[2]),
                     qd * (k0[0] * k1[0] + k0[1] * k1[1] + k0[2] * k1[2]),
                     qd * (k0[0] * k2[0] + k0[1] * k2[1] + k0[2] * k2[2]),
                     qd * (k1[0] * k1[0] + k1[1] * k1[1] + k1[2] * k1[2]),
                     qd * (k1[0] * k2[0] + k1[1] * k2[1] + k1[2] * k2[2]),
                     qd * (k2[0] * k2[0] + k2[1] * k2[1] + k2[2] * k2[2]), qa]
            s4 = qa * k / w0
            sig2 = qa * (1.0 + k * k) / ww
            if biases:
                for j in range(3):
                    a_dyn.extend((-k0[j], -k1[j], -k2[j]))
                a_dyn.extend((-n_b0, -n_b1, -n_b2))
                hneg[ia] = -w0 / w0
                hneg[ia + 1] = -u_b1 / w0
                hneg[ia + 2] = -u_b2 / w0
            return first, a_dyn, hneg, q_dyn, s4, sig2

        return fused

    def _kphi_c(self, phi: float) -> float:
        """d k / d phi on the ellipsoid, by the same formula as in the stage function."""
        lam, dlam, ddlam, hh, dh = self.track_functions.scalars(phi)
        sp, cp = math.sin(phi), math.cos(phi)
        e2 = self._e2
        w = 1.0 - e2 * sp * sp
        r_e = self._a / math.sqrt(w)
        r_n = r_e * (1.0 - e2) / w
        rn, re = r_n + hh, r_e + hh
        dre = r_e * e2 * sp * cp / w + dh
        drn = 3.0 * r_n * e2 * sp * cp / w + dh
        ratio = re / rn
        return (ddlam * cp - dlam * sp) * ratio + dlam * cp * (dre - ratio * drn) / rn
