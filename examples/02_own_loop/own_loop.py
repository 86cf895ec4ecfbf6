import numpy as np

import sdbc_evolution as sd

kw = dict(attributes=(), min_size=1, max_size=1, geometry="point")
robot = sd.EntityGroupSpec(name="Robot", static=False, **kw)
beacon = sd.EntityGroupSpec(name="Beacon", static=True, **kw)
task, N, T = sd.TaskDescription("beacon", (robot, beacon)), 40, 3
search = sd.NoveltySearch("ns-sd+", genome_length=6, population=N, seed=0, task=task)
here = sd.GroupState(np.ones((1, 1), bool), np.zeros((1, 1, 0)), np.zeros((1, 1, 2)))
rng = np.random.default_rng(1)
for _ in range(25):
    w = np.repeat(search.ask(), T, axis=0).reshape(N * T, 3, 2)  # trial b: b // T's
    x, states = rng.uniform(-5, 5, (N * T, 2)), []
    for step in range(1, 61):
        x = x + 0.3 * np.tanh(np.einsum("bi,bij->bj", -x / 5, w[:, :2]) + w[:, 2])
        me = sd.GroupState(np.ones((1, 1), bool), np.zeros((1, 1, 0)), x[:, None])
        states.append(sd.TaskState(step, np.ones(N * T, bool), (me, here)))
    search.tell(1 - np.minimum(np.hypot(*x.T) / 7, 1).reshape(N, T), states)
print(f"best fitness {search.best.fitness:.3f}, generation {search.best.generation}")
