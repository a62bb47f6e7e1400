"""Light and materials: the material and light records (:mod:`.material`), the
lighting formulas of docs/formulas.md (:mod:`.lighting`), 2D textures (:mod:`.texture`),
cube maps (:mod:`.cubemap`) and shadow-map lookups (:mod:`.shadowmap`).
"""
