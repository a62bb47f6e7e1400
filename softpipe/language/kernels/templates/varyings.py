"""Template of one varying component at a fragment, by qualifier, and of its derivatives.

``interpolate`` (templates/fragment.py) holds one of these expressions per
component of each varying: the generator (kernels/generate.py) copies the
expression a function below returns (kernels/template.py,
``template_expression``), with

- ``K``: the component's column of ``corner`` ([triangle, corner, column]: the
  varyings at the triangle's three corners, after primitive assembly);
- ``AXIS``: 0 for ∂/∂x, 1 for ∂/∂y (``bary_grad[t, AXIS, k]`` = ∂b_k along it);
- ``V``: the component's value (``v_normal[1]``), ``DQ``: ∂ of the weights' sum (``dqx``).

The weights (``interpolate``): b_k the window-space barycentrics, q_k = b_k / w_k,
r = 1 / Σ q_k. A smooth varying is v = A / B with A = Σ q_k v_k and B = Σ q_k,
so its derivative is ∂v = (∂A − v ∂B) / B; a noperspective one is linear in the
window, ∂v = Σ ∂b_k v_k; a flat one is constant. docs/design.md, stage 4,
says why the qualifiers differ; docs/05-fragment.md shows one
worked through.
"""


def smooth(t, K, q0, q1, q2, r, corner):
    """Perspective-correct: (Σ q_k v_k) · (1 / Σ q_k)."""
    return (q0 * corner[t, 0, K] + q1 * corner[t, 1, K] + q2 * corner[t, 2, K]) * r


def noperspective(t, K, b0, b1, b2, corner):
    """Linear in window space: Σ b_k v_k."""
    return b0 * corner[t, 0, K] + b1 * corner[t, 1, K] + b2 * corner[t, 2, K]


def flat(t, K, corner):
    """The provoking vertex's value, which primitive assembly copied to every corner."""
    return corner[t, 2, K]


def weights_derivative(t, AXIS, bary_grad, inv_w):
    """∂B = Σ ∂b_k / w_k, the derivative of the smooth weights' sum (written once per axis)."""
    return bary_grad[t, AXIS, 0] * inv_w[t, 0] + bary_grad[t, AXIS, 1] * inv_w[t, 1] + bary_grad[t, AXIS, 2] * inv_w[t, 2]


def smooth_derivative(t, AXIS, K, V, DQ, qs, bary_grad, inv_w, corner):
    """(∂A − v ∂B) / B, with ∂A = Σ ∂b_k v_k / w_k."""
    return (bary_grad[t, AXIS, 0] * inv_w[t, 0] * corner[t, 0, K] + bary_grad[t, AXIS, 1] * inv_w[t, 1] * corner[t, 1, K] + bary_grad[t, AXIS, 2] * inv_w[t, 2] * corner[t, 2, K] - V * DQ) / qs


def noperspective_derivative(t, AXIS, K, bary_grad, corner):
    """Σ ∂b_k v_k."""
    return bary_grad[t, AXIS, 0] * corner[t, 0, K] + bary_grad[t, AXIS, 1] * corner[t, 1, K] + bary_grad[t, AXIS, 2] * corner[t, 2, K]


def flat_derivative():
    """A flat varying does not change across the triangle."""
    return 0.0
