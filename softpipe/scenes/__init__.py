"""What to draw: meshes (:mod:`.mesh`), OBJ files (:mod:`.obj`), generated shapes
(:mod:`.shapes`), the bundled models (:mod:`.models`), the scene model (:mod:`.scene`) and
scene files (:mod:`.scenefile`); drawing a scene (:mod:`.drawing`) with its shadow-map pass
(:mod:`.shadow_pass`) and environment pass (:mod:`.environment_pass`).
"""
