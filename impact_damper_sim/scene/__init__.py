"""Scene files: declarative schema, validation and unit conversion at load (no rclpy)."""
from .schema import (
    REQUIRED, Boolean, Choice, Field, Integer, KeyInfo, ListOf, MapOf, Optional, Quantity,
    SceneError, Section, String, Vector, apply_overrides, describe, load_scene, load_yaml,
    markdown_table, validate,
)

__all__ = [
    'REQUIRED', 'Boolean', 'Choice', 'Field', 'Integer', 'KeyInfo', 'ListOf', 'MapOf',
    'Optional', 'Quantity', 'SceneError', 'Section', 'String', 'Vector', 'apply_overrides',
    'describe', 'load_scene', 'load_yaml', 'markdown_table', 'validate',
]
