# Lesson 07, the exercise completed: the OpenGL lighting equation for one directional light (FORMULAS §10),
# Blinn–Phong's specular (N·H)ⁿ (§6), in eye space.

import numpy as np


def blinn_phong(P, N, L, material, light, global_ambient):
    """I = k_e + k_a·I_a,global + k_a·I_a + B·(k_d·I_d·(N·L) + k_s·I_s·(N·H)₊ⁿ), B = 1 where N·L > 0."""
    m = material
    N = N / np.linalg.norm(N)                  # interpolated normals are shorter than 1: renormalize (§12)
    V = -P / np.linalg.norm(P)                 # toward the eye, at the origin of eye space
    L = np.asarray(L)
    color = np.asarray(m.ke) + np.asarray(m.ka) * (np.asarray(global_ambient) + np.asarray(light.ambient))
    n_dot_l = N @ L
    if n_dot_l > 0:
        H = (L + V) / np.linalg.norm(L + V)
        color = color + np.asarray(m.kd) * np.asarray(light.diffuse) * n_dot_l
        color = color + np.asarray(m.ks) * np.asarray(light.specular) * max(N @ H, 0.0) ** m.shininess
    return color
