"""The sensitivity node across processes (remesher, a solver, sensitivity): a
press on a sloper option gets its Ψ on ``psi/fine`` (and no mesh), drags get
predictions on the fine mesh of exactly the client's design, and the release
prediction closes the gesture."""

from __future__ import annotations

import time
import uuid

import numpy as np
import pytest

from couture import supervisor
from couture.bus import BusConfig, free_port
from couture.client import Client
from schemas import MeshMsg, PsiMsg
from schemas.design import Design, Resolution, Sloper

pytestmark = [pytest.mark.timeout(300), pytest.mark.slow]

SMALL = Design(sloper=Sloper(kind="skirt"), resolution=Resolution(coarse_vertices=300, fine_vertices=900))


def camera() -> np.ndarray:
    """View-projection (world [m] -> clip) of a camera 2.6 m in front of the
    mannequin (+z) looking at it, y up (the UI's initial view)."""
    f, near, far = 1.0 / np.tan(np.deg2rad(25.0)), 0.1, 10.0
    proj = np.array(
        [[f, 0, 0, 0], [0, f, 0, 0], [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)], [0, 0, -1, 0]]
    )
    view = np.eye(4)
    view[:3, 3] = [0.0, -0.15, -2.6]
    return proj @ view


def wait_for(cond, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = cond()
        if v:
            return v
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def test_press_drag_release_predicts_on_the_clients_design():
    session = f"s{uuid.uuid4().hex[:8]}"
    nodes = supervisor.default_nodes(solvers=["newton"], ui=False)
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=session, listen=[f"tcp/127.0.0.1:{free_port()}"]),
        nodes=[n for n in nodes if n.name != "recorder"],
    )
    with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as client:
        client.wait_nodes(["remesher", "solver-newton", "sensitivity"], timeout=60)
        gen = client.publish_pattern(SMALL, name="small")
        fine = client.wait_drape("fine", generation=gen, timeout=200, final=True)
        n = fine.x.shape[0]
        wait_for(
            lambda: (st := client.status.get("sensitivity")) is not None and st.counters.get("refactors", 0) >= 1,
            60,
            "the sensitivity node's refactorization at the drape",
        )
        psis: list[PsiMsg] = []
        meshes: list[MeshMsg] = []
        client.bus.subscribe("psi/*", psis.append, PsiMsg)
        client.bus.subscribe("mesh/*", meshes.append, MeshMsg)
        time.sleep(0.5)  # the meshes kept as history arrive first
        meshes.clear()
        edit = client.send_edit("param:length", [0.0, 0.0], phase="press", param="length", dofs=["length"])
        got = wait_for(
            lambda: [m for m in psis if m.level == "fine" and m.edit_id == edit.edit_id],
            30,
            "the remesher's Ψ for the press",
        )[0]
        assert got.mesh_generation == fine.mesh_generation and got.generation == fine.generation
        assert got.psi.numpy().shape == (n, 2, 2) and np.any(got.psi.numpy())
        wait_for(lambda: any(m.level == "coarse" and m.edit_id == edit.edit_id for m in psis), 10, "the coarse Ψ")
        assert not meshes, "a press moves Ψ alone, no mesh"
        # Ψ is the topic's history: a node that joins mid-drag (a restart) gets the gesture's
        late: list[PsiMsg] = []
        with Client(bus=sup.child_bus) as joiner:
            joiner.bus.subscribe("psi/fine", late.append, PsiMsg)
            wait_for(lambda: late, 10, "the last Ψ for a late joiner")
        assert late[-1].edit_id == edit.edit_id and late[-1].mesh_generation == fine.mesh_generation
        mine = []

        def predicted() -> list:
            mine[:] = [d for d in client.drapes("predicted") if d.edit_id == edit.edit_id]
            return mine

        for k in range(1, 30):
            client.send_edit(
                "param:length", [0.002 * k, 0.0], phase="drag", edit_id=edit.edit_id, param="length", dofs=["length"]
            )
            time.sleep(0.1)
            if predicted():
                break
        wait_for(predicted, 30, "a prediction for the drag")
        p = mine[-1]
        assert p.x.shape[0] == n and p.generation == fine.generation and p.mesh_generation == fine.mesh_generation
        assert p.method in ("linear", "gmls") and np.all(np.isfinite(p.x.numpy()))
        # a longer skirt: the predicted hem is lower than the drape's
        assert p.x.numpy()[:, 1].min() < fine.x.numpy()[:, 1].min()
        client.send_edit(
            "param:length", [0.05, 0.0], phase="release", edit_id=edit.edit_id, param="length", dofs=["length"]
        )
        wait_for(lambda: any(d.diagnosis == "release" for d in predicted()), 30, "the release prediction")
        # (a status goes out once a second: the one that counts the press may predate the predictions)
        st = wait_for(
            lambda: (
                (m := client.status.get("sensitivity")) is not None
                and m.counters.get("press_columns", 0) >= 1
                and m.counters.get("predictions", 0) >= 2
                and m
            ),
            10,
            "the press and the predictions counted in status",
        )
        assert not st.last_error, st

        # a 3D tug of the hem (the sloper's length): its release publishes the
        # edited design, which the remesher numbers and meshes
        x = fine.x.numpy()
        hem = int(np.argmin(x[:, 1] - 0.1 * x[:, 2]))  # low, in front
        tug = client.send_edit(
            "",
            [0.0, 0.0],
            phase="press",
            param="length",
            picked_vertex=hem,
            view_proj=camera(),
            viewport_px=[800, 800],
            dofs=["length"],
        )
        wait_for(lambda: any(m.edit_id == tug.edit_id for m in psis), 30, "the remesher's Ψ for the tug")
        time.sleep(0.5)  # the columns
        client.send_edit(
            "",
            [0.0, 40.0],
            phase="release",
            edit_id=tug.edit_id,
            param="length",
            picked_vertex=hem,
            view_proj=camera(),
            viewport_px=[800, 800],
            dofs=["length"],
        )
        new = wait_for(
            lambda: (m := client.latest_mesh("fine")) is not None and m.generation > gen and m,
            60,
            "the mesh of the tugged design",
        )
        assert new.design_id and new.mesh_generation > fine.mesh_generation


def test_a_press_at_once_after_the_drape_is_held_until_the_equilibrium():
    """A script presses the moment the final fine drape arrives, while the node
    still refactors at it: the press is held, not dropped, and predicted once
    the equilibrium is there; the status then says predictions are ready for
    that design, and the client can wait on it."""
    session = f"s{uuid.uuid4().hex[:8]}"
    nodes = supervisor.default_nodes(solvers=["newton"], ui=False)
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=session, listen=[f"tcp/127.0.0.1:{free_port()}"]),
        nodes=[n for n in nodes if n.name != "recorder"],
    )
    with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as client:
        client.wait_nodes(["remesher", "solver-newton", "sensitivity"], timeout=60)
        gen = client.publish_pattern(SMALL, name="small")
        fine = client.wait_drape("fine", generation=gen, timeout=200, final=True)
        edit = client.send_edit("param:length", [0.0, 0.0], phase="press", param="length", dofs=["length"])
        for k in range(1, 4):  # drags while the press may still be held
            client.send_edit(
                "param:length", [0.01 * k, 0.0], phase="drag", edit_id=edit.edit_id, param="length", dofs=["length"]
            )
        mine = wait_for(
            lambda: [d for d in client.drapes("predicted") if d.edit_id == edit.edit_id],
            30,
            "a prediction for the press sent right after the drape",
        )
        p = mine[-1]
        assert p.generation == fine.generation and p.mesh_generation == fine.mesh_generation
        assert p.x.shape == fine.x.shape and np.all(np.isfinite(p.x.numpy()))
        st = client.wait_predictions_ready(timeout=30, generation=gen)
        assert st.ready and st.ready_generation == fine.generation
        assert st.ready_mesh_generation == fine.mesh_generation
        client.send_edit(
            "param:length", [0.03, 0.0], phase="release", edit_id=edit.edit_id, param="length", dofs=["length"]
        )
        wait_for(
            lambda: any(d.edit_id == edit.edit_id and d.diagnosis == "release" for d in client.drapes("predicted")),
            30,
            "the release prediction",
        )
        st = client.status["sensitivity"]
        assert st.counters.get("gestures_expired", 0) == 0 and not st.last_error, st
        with pytest.raises(TimeoutError, match="not ready for generation"):
            client.wait_predictions_ready(timeout=0.5, generation=gen + 5)
