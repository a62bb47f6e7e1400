# Lesson 04, the exercise completed: a smooth varying, perspective-correct.


def interpolate(values, inv_w, bary):
    """The varying at a fragment from the corners' ``values`` [3, n], their 1/w [3] and the fragment's
    window-space barycentrics [3]: v = Σ (b_k / w_k) v_k / Σ (b_k / w_k)."""
    weights = bary * inv_w
    return weights @ values / weights.sum()
