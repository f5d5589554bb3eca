"""The paper's grasp controller on planar convex polygons (sections 3-4, Appendices A-B).

Pure numpy/scipy/clarabel (and torch for the predictor): imports no MuJoCo and no other package
of graspsim, so it can be used on its own.
"""

from controllers.grasp.composition import Composer, KnowledgeBased, luce_activation
from controllers.grasp.errors import (
    GraspError,
    ModelNotTrainedError,
    PolygonError,
    UnknownNameError,
)
from controllers.grasp.objects import (
    PAPER_OBJECTS,
    paper_object,
    random_convex_polygon,
    regular_polygon,
)
from controllers.grasp.polygon import ContactFrames, Polygon, locate_contacts
from controllers.grasp.prism import ContactFrames3D, Prism, locate_contacts_3d
from controllers.grasp.prism3d import physical_tasks, prism_contacts, worst_task_score
from controllers.grasp.score import SUCCESS_THRESHOLD, GraspScore, grasp_score
from controllers.grasp.score3d import ContactError, GraspScore3D, grasp_score_3d
from controllers.grasp.state import ControlState
from controllers.grasp.trials import PolygonBatch, TrialBatch, run_trials

__all__ = [
    "PAPER_OBJECTS",
    "SUCCESS_THRESHOLD",
    "Composer",
    "ContactError",
    "ContactFrames",
    "ContactFrames3D",
    "ControlState",
    "GraspError",
    "GraspScore",
    "GraspScore3D",
    "KnowledgeBased",
    "ModelNotTrainedError",
    "Polygon",
    "PolygonBatch",
    "PolygonError",
    "Prism",
    "TrialBatch",
    "UnknownNameError",
    "grasp_score",
    "grasp_score_3d",
    "locate_contacts",
    "locate_contacts_3d",
    "luce_activation",
    "paper_object",
    "physical_tasks",
    "prism_contacts",
    "random_convex_polygon",
    "regular_polygon",
    "run_trials",
    "worst_task_score",
]
