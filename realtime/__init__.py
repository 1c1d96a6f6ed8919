"""Real-time GLSL split-sum renderer through headless moderngl."""
