"""The PBASIC templates (templates/pbasic/*.j2), shipped inside the wheel as bstool.templates.

pyproject.toml maps this folder into the package; bstool.compile.render finds the templates
with importlib.resources, in a wheel install and in an editable one alike.
"""
