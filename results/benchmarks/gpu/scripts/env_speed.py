# Env stepping alone on the GPU: halfcheetah (gymnasium v5 on MJX), jitted scan of vmapped steps.
import sys, time, json
import jax, jax.numpy as jnp
sys.path.insert(0, ".")
import envs
steps = 200
for n, kw in [(8, {}), (8, {"early_exit_linesearch": False}), (512, {}), (512, {"early_exit_linesearch": False})]:
    env = envs.make("halfcheetah", **kw)
    def run(state, key):
        def step(s, k):
            a = jax.random.uniform(k, (n, env.action_size), jnp.float32, -1.0, 1.0)
            s = jax.vmap(env.step)(s, a)
            return s, s.reward
        return jax.lax.scan(step, state, jax.random.split(key, steps))
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), n))
    t = time.perf_counter(); fn = jax.jit(run).lower(state, jax.random.PRNGKey(1)).compile(); c = time.perf_counter() - t
    jax.block_until_ready(fn(state, jax.random.PRNGKey(1)))
    ts = []
    for r in range(2):
        t = time.perf_counter(); jax.block_until_ready(fn(state, jax.random.PRNGKey(2 + r))); ts.append(time.perf_counter() - t)
    print(json.dumps({"num_envs": n, "overrides": kw, "steps": steps, "compile_s": round(c, 1), "times": ts,
                      "total_steps_per_s": round(n * steps / min(ts)), "ms_per_step": round(1000 * min(ts) / steps, 2)}), flush=True)
