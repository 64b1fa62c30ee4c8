"""Scene files: declarative schema, validation and unit conversion at load (no rclpy).

A scene is YAML text checked against a schema: every quantity may carry a unit and comes
out in SI, every problem is one line naming its key. The shipped scenes' schema is
:data:`.spec.SCHEMA`; :func:`impact_damper_sim.scene.build.load` loads a scene and builds
its model (the package's quick tour, :mod:`impact_damper_sim`). A schema of two keys:

>>> from impact_damper_sim.scene import (Quantity, SceneError, Section, apply_overrides,
...                                      load_yaml, validate)
>>> schema = Section({'mass': Quantity('mass'),
...                   'clearance': Quantity('length', default='2 mm', min=0.0)})
>>> raw = load_yaml('mass: 5 lb   # a comment')
>>> validate(schema, raw)
{'mass': 2.26796185..., 'clearance': 0.002}
>>> validate(schema, apply_overrides(raw, ['clearance=0.1 in']))['clearance']
0.00254
>>> try:
...     validate(schema, {'mass': '2 kg', 'clearance': '-1 mm'}, source='demo.yaml')
... except SceneError as exc:
...     print(exc)
demo.yaml: scene key 'clearance': -1 mm = -0.001 m is out of range [0, inf) m (= [0, inf) mm)
"""
from .containers import ListOf, MapOf, Optional, Section, Vector
from .keytable import describe, markdown_table
from .loading import apply_overrides, load_scene, load_yaml
from .schema import (
    REQUIRED,
    Boolean,
    Choice,
    Field,
    Integer,
    KeyInfo,
    Quantity,
    SceneError,
    String,
    validate,
)

__all__ = [
    'REQUIRED', 'Boolean', 'Choice', 'Field', 'Integer', 'KeyInfo', 'ListOf', 'MapOf',
    'Optional', 'Quantity', 'SceneError', 'Section', 'String', 'Vector', 'apply_overrides',
    'describe', 'load_scene', 'load_yaml', 'markdown_table', 'validate',
]
