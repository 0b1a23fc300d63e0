# As run on the device: the Python file was carried there as .whl/gpu_env.py; it is kept here as env_speed.py.
export PYTHONUNBUFFERED=1 MUJOCO_GL=disable
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD
timeout 190 python3 .whl/gpu_env.py 2>&1 | grep -v -i warp | tee $OUT/gpu_env.log
