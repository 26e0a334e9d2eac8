"""Scenes: several surfaces, a representative trajectory, and a planner that renders only what matters (docs/scenes.md)."""
