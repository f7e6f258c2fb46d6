"""Laminate modes: three bending sections of the cantilever as a chain of lumped masses (Eq. 1, 3)."""

from __future__ import annotations

from board_config.parameter_sets import core_parameters
from plant.effect import PhysicalEffect
from plant.layout import B_S, B_Z, B_ZD, P_C, P_K, X_DDELTA, X_DELTA


class LaminateModes(PhysicalEffect):
    """Shear chain of three masses: m_j z̈_j = S_j − S_{j+1} + F_mj − m_j z̈0 (z relative to the base).

    Section i contributes its elastic and structural-damping force to the section force
    S_i = −k_i δ_i − c_i δ̇_i (+ piezo and added forces from other effects); z_i = δ_1 + … + δ_i.
    """

    name = "laminate"
    role = "core"
    description = "Three bending sections (masses m_i, stiffness k_i, structural damping c_i)"
    origin = "Seed paper Eq. (1)-(3): lumped-parameter cantilever with three bending deformations"
    parameters = core_parameters("m1", "m2", "m3", "k1", "k2", "k3", "c1", "c2", "c3")

    @staticmethod
    def pre(t, x, p, bus, dx, X, P, B):
        z = 0.0
        zd = 0.0
        for i in range(3):
            z += x[X_DELTA + i]
            zd += x[X_DDELTA + i]
            bus[B_Z + i] = z
            bus[B_ZD + i] = zd

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        for i in range(3):
            dx[X_DELTA + i] = x[X_DDELTA + i]
            bus[B_S + i] += -p[P_K + i] * x[X_DELTA + i] - p[P_C + i] * x[X_DDELTA + i]

    @staticmethod
    def post(t, x, p, bus, dx, X, P, B):
        z0dd = bus[B.z0dd]
        a1 = (bus[B.s1] - bus[B.s2] + bus[B.fm1]) / p[P.m1] - z0dd
        a2 = (bus[B.s2] - bus[B.s3] + bus[B.fm2]) / p[P.m2] - z0dd
        a3 = (bus[B.s3] + bus[B.fm3]) / p[P.m3] - z0dd
        dx[X.ddelta1] += a1
        dx[X.ddelta2] += a2 - a1
        dx[X.ddelta3] += a3 - a2
