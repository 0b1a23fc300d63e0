# Env stepping alone on the GPU (session 14): HalfCheetah (gymnasium v5 on MJX) at N vmapped envs, a jitted
# 200-step scan, best of 3 timed calls after a warm one; the same measurement as env_speed.py's default rows.
# Run once per XLA_FLAGS setting (det_ops.sh) to price --xla_gpu_deterministic_ops=true.
import json, os, sys, time
import jax, jax.numpy as jnp
sys.path.insert(0, ".")
import metapg_jax  # noqa: F401  (adds --xla_gpu_deterministic_ops=true unless XLA_FLAGS sets it)
import envs
n, steps = int(sys.argv[1]), 200
env = envs.make("halfcheetah")
def run(state, key):
    def step(s, k):
        s = jax.vmap(env.step)(s, jax.random.uniform(k, (n, env.action_size), jnp.float32, -1.0, 1.0))
        return s, s.reward
    return jax.lax.scan(step, state, jax.random.split(key, steps))
state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), n))
t = time.perf_counter(); fn = jax.jit(run).lower(state, jax.random.PRNGKey(1)).compile(); c = time.perf_counter() - t
rewards = jax.block_until_ready(fn(state, jax.random.PRNGKey(1))[1])
ts = []
for r in range(3):
    t = time.perf_counter(); jax.block_until_ready(fn(state, jax.random.PRNGKey(2 + r))); ts.append(time.perf_counter() - t)
print(json.dumps({"xla_flags": os.environ.get("XLA_FLAGS"), "backend": jax.default_backend(), "num_envs": n,
                  "steps": steps, "compile_s": round(c, 1), "times": ts, "total_steps_per_s": round(n * steps / min(ts)),
                  "ms_per_step": round(1000 * min(ts) / steps, 2), "reward_sum_key1": float(rewards.sum())}), flush=True)
