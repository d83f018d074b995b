"""rasm.workflow: the engineering workflow (model, generate, package, deploy).

Architecture model (``model.yaml``) → lint (:func:`lint_model`) → application skeleton
(:func:`new_app`, ``rasm new``) → deployment package (:func:`package_app`, ``rasm package``) →
verified deployment of one compute unit (:func:`deploy_package`, ``rasm deploy``).
"""

from rasm.workflow.checks import check_model, lint_model
from rasm.workflow.deploy import DeployError, DeployReport, deploy_package, run_workflow
from rasm.workflow.derive import app_config, model_from_manifest
from rasm.workflow.generate import Generated, GenerateError, generate_app, new_app
from rasm.workflow.integrity import IntegrityError, configured_key
from rasm.workflow.model import ArchitectureModel, load_model, parse_model
from rasm.workflow.package import PackageError, PackageReport, package_app

__all__ = [
    "ArchitectureModel",
    "DeployError",
    "DeployReport",
    "GenerateError",
    "Generated",
    "IntegrityError",
    "PackageError",
    "PackageReport",
    "app_config",
    "check_model",
    "configured_key",
    "deploy_package",
    "generate_app",
    "lint_model",
    "load_model",
    "model_from_manifest",
    "new_app",
    "package_app",
    "parse_model",
    "run_workflow",
]
