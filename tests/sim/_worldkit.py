
from socialnav.scenarios import make_scenario
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World


def hand_world(n_humans: int = 1, batch: int = 1, **settings) -> World:
    """A world whose state the test overwrites by hand after reset (scenario only sizes it)."""
    settings.setdefault("threads", 1)
    world = World(WorldSettings(**settings), make_scenario("circle_crossing", n_humans=n_humans), batch,
                  split="test", count=batch)
    world.reset()
    world.velocity[:] = 0.0
    return world


def place(world: World, agent: int, position, goal, radius: float = 0.3, v_pref: float = 1.0, slot: int = 0):
    world.position[slot, agent] = position
    world.goal[slot, agent] = goal
    world.radius[slot, agent] = radius
    world.v_pref[slot, agent] = v_pref


