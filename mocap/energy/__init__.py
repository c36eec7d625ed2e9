"""Energies of a pose hypothesis, batched over particles: (P, D) -> (P,).

E(chi) = E_S(chi) + lambda E_R(chi) + E_P(chi)   (Zhang et al. 2013, Eq. 10)
"""
