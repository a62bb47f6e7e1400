"""The lessons' completed exercises, one module per notebook (``NN_name.py``).

Each module holds exactly the functions its notebook's exercise cell (the cell tagged
``exercise``) asks for, under the same names: ``tests/test_lessons.py`` runs every notebook
once with that cell as it is (the skeleton: its check must fail, helpfully) and once with
the cell's source replaced by this module's text (its check must pass).
"""
