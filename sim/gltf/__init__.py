"""glTF 2.0 import and export of animated characters (Khronos glTF 2.0 specification, version 2.0.1).

The modules in data-flow order, file -> container -> scene graph -> primitives / animation -> load -> Character;
import from them (``from sim.gltf.load import load_gltf``), this package exports nothing:

- ``sim.gltf.container``: the ``.glb``/``.gltf`` file as a checked JSON document, its buffers and its accessors as numpy arrays (§3.6 binary data storage, chapter 4 GLB).
- ``sim.gltf.scene_graph``: the node hierarchy, local and world transforms, the default scene's nodes (§3.5 scenes, nodes and transformations).
- ``sim.gltf.primitives``: a mesh primitive's triangles, colours (texture sampled), skin attributes and morph targets, baked to a node's space (§3.7.2 meshes, §3.8 textures, §3.9 materials).
- ``sim.gltf.animation``: animation samplers, key times and values checked (§3.11 animations, Appendix C interpolation).
- ``sim.gltf.load``: ``load_gltf``, the default scene as one SkinnedCharacter (skins, joints, clips; morph targets and their weights channels kept, played before skinning) or KeyframedCharacter (morph animations of unskinned meshes) (§3.7.3 skins, §3.7.2.2 morph targets).

Apart from that flow:

- ``sim.gltf.write``: ``save_glb``, either character kind (a skinned one with its morph targets) written back as a binary glTF through pygltflib (§3.6, §3.7, §3.11, chapter 4).
"""
