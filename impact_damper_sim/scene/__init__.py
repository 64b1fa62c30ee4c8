"""Scene files: declarative schema, validation and unit conversion at load (no rclpy)."""
from .containers import ListOf, MapOf, Optional, Section, Vector
from .keytable import describe, markdown_table
from .loading import apply_overrides, load_scene, load_yaml
from .schema import (
    REQUIRED, Boolean, Choice, Field, Integer, KeyInfo, Quantity, SceneError, String, validate,
)

__all__ = [
    'REQUIRED', 'Boolean', 'Choice', 'Field', 'Integer', 'KeyInfo', 'ListOf', 'MapOf',
    'Optional', 'Quantity', 'SceneError', 'Section', 'String', 'Vector', 'apply_overrides',
    'describe', 'load_scene', 'load_yaml', 'markdown_table', 'validate',
]
