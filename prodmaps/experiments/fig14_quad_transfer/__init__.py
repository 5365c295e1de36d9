"""Figure 14: cross fields and quad meshes transferred through a functional map, std vs products.

``crossfields`` (the cross fields through a map, the joint design, the measures and verdicts),
``plots`` (their figures) and ``quads`` (quad meshes transported by point maps). Importing this
package imports nothing.
"""
