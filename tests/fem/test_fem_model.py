"""Both FEM models keep one protocol (`fem_model.FemModel`): what the Newton solver, the
limits, the reduced model's build and the stages read of a model, the same names on
both, with the values each model stands for."""

import numpy as np
import pytest

from fruitcli.fem.continuum import DILATATION_STEP, ContinuumModel
from fruitcli.fem.corotational_model import Model
from fruitcli.fem.elements.quadratic import quadratic_mesh
from fruitcli.fem.fem_model import BulkStaged, FemModel
from fruitcli.fem.materials.build import material
from fruitcli.fem.meshing.grid import structured_box


def box():
    nodes, tets = structured_box([0, 0, 0], [2, 1, 1], [2, 1, 1])
    return nodes, tets, np.flatnonzero(nodes[:, 0] == 0.0)


def test_the_corotational_model_keeps_the_protocol():
    nodes, tets, held = box()
    m = Model.from_arrays(nodes, tets, 100.0, 0.45, fixed_nodes=held)
    assert isinstance(m, FemModel)
    assert m.elements is m.tets and m.elements.shape == (len(tets), 4)
    assert (m.element_name, m.material_name) == ("p1", "corotational")
    assert m.bulk_stages() == [] and m.dilatation_step == 0.0
    assert m.escalate_on_damping and m.secant_while_rotating
    assert not isinstance(m, BulkStaged)  # solved at its own bulk modulus
    x = m.rest * 1.1  # a uniform 10 % stretch: each tet's volume ratio 1.1^3
    np.testing.assert_allclose(m.mean_dilatation(x), 1.1**3, rtol=1e-12)


@pytest.mark.parametrize(("element", "per_tet"), [("p1", 4), ("p2", 10)])
def test_the_hyperelastic_model_keeps_the_protocol(element, per_tet):
    """Its elements are the full connectivity (10 nodes on p2), its tets the corners; at
    nu = 0.49 nu = 0.4999 a state from rest passes through bulk-modulus stages below kappa."""
    nodes, tets, held = box()
    if element == "p2":
        nodes, tets, _ = quadratic_mesh(nodes, tets, [])
    mat = material("neo-hookean", 100.0, 0.4999)  # kappa = 5000 mu
    m = ContinuumModel.from_arrays(nodes, tets, mat, element, fixed_nodes=held)
    assert isinstance(m, FemModel)
    assert m.elements.shape == (len(tets), per_tet)
    assert np.array_equal(m.tets, m.elements[:, :4])
    assert (m.element_name, m.material_name) == (element, "neo-hookean")
    mu = mat.shear_modulus_kpa  # stages 50 mu, 500 mu (5000 mu is past kappa / 2)
    assert m.bulk_stages() == pytest.approx([50.0 * mu, 500.0 * mu])
    assert m.dilatation_step == pytest.approx(DILATATION_STEP * mu / mat.bulk_modulus_kpa)
    assert not m.escalate_on_damping and not m.secant_while_rotating
    assert isinstance(m, BulkStaged)
    assert m.chamber_gradients(m.rest).shape == (0, m.n_nodes, 3)  # no chamber


def test_an_object_missing_a_member_is_not_a_model():
    class Partial:
        rest = np.zeros((4, 3))

    assert not isinstance(Partial(), FemModel)
