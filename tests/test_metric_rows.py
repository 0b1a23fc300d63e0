"""metapg_jax.host.metric_rows: the rows a run writes and what is read back from them."""


def test_training_seconds_add_up_every_call():
    from metapg_jax.host import metric_rows

    def rows(walls, chunk_seconds=None, seeds=2):
        return [{"seed": s, "chunk": c, "wall_time": w, **({} if chunk_seconds is None else
                                                              {"chunk_seconds": chunk_seconds[c]})}
                for c, w in enumerate(walls) for s in range(seeds)]

    # older rows (wall_time only): a call of 3 chunks, killed, resumed for 2 (its clock restarts at 0)
    assert metric_rows.training_seconds(rows([10.0, 20.0, 30.0, 5.0, 15.0])) == (45.0, False)
    # rows with chunk_seconds add up exactly, also where the clock restart is invisible in wall_time
    exact = rows([10.0, 40.0, 50.0], chunk_seconds=[10.0, 40.0, 10.0])
    assert metric_rows.training_seconds(exact) == (60.0, True)
    assert metric_rows.training_seconds([{"seed": 0, "chunk": 0}]) == (None, False)
