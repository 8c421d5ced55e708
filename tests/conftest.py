import os

# headless rendering for tests (our viewer still draws, see icv_envs.envs.rendering)
os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
