"""Identification of a model on one experiment and validation on another: the records read and prepared in one call
(the derivatives chosen by held-out evidence, on another motion when a validation record holds one), plain, shaped and delayed fits, the model's parameter vector as JSON,
trivial predictors.

Modules: :mod:`~estimation.identification.delayed`, :mod:`~estimation.identification.fit`, :mod:`~estimation.identification.joint_zeros`, :mod:`~estimation.identification.model_parameters`, :mod:`~estimation.identification.prepared`, :mod:`~estimation.identification.preprocessing_choice`, :mod:`~estimation.identification.preprocessing_on_validation`, :mod:`~estimation.identification.record_changes`, :mod:`~estimation.identification.shaped`, :mod:`~estimation.identification.training_range`, :mod:`~estimation.identification.trivial_predictors`, :mod:`~estimation.identification.validation`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "ChoiceWindow": "estimation.identification.preprocessing_choice",
    "ChannelErrors": "estimation.identification.validation",
    "Comparison": "estimation.identification.validation",
    "DelayFit": "estimation.identification.delayed",
    "EQUIVALENT": "estimation.identification.preprocessing_choice",
    "ExtrapolationWarning": "estimation.identification.training_range",
    "HeldOutScore": "estimation.identification.preprocessing_choice",
    "IdentificationResult": "estimation.identification.fit",
    "IdentifiedModel": "estimation.identification.identified_model",
    "ImplausibleEstimateWarning": "estimation.identification.fit",
    "InMemoryBudget": "estimation.identification.prepared",
    "JointZeroCheck": "estimation.identification.joint_zeros",
    "JointZeroWarning": "estimation.identification.joint_zeros",
    "MjcfExport": "estimation.identification.export",
    "ModelFile": "estimation.identification.model_file",
    "ModelFileError": "estimation.identification.model_file",
    "PreparationSettings": "estimation.identification.prepared",
    "PreparedRecords": "estimation.identification.prepared",
    "PreprocessingChoice": "estimation.identification.preprocessing_choice",
    "REPEAT_FRACTION": "estimation.identification.repeated_motion",
    "RangeCheck": "estimation.identification.training_range",
    "RecordChanges": "estimation.identification.record_changes",
    "RobotSource": "estimation.identification.model_file",
    "SCORED_SAMPLES": "estimation.identification.preprocessing_choice",
    "TrainingRange": "estimation.identification.training_range",
    "ShapeValue": "estimation.identification.shaped",
    "assess_plausibility": "estimation.identification.plausibility",
    "check_record_changes": "estimation.identification.record_changes",
    "check_joint_zeros": "estimation.identification.joint_zeros",
    "choose_by_evidence": "estimation.identification.preprocessing_choice",
    "choose_on_validation": "estimation.identification.preprocessing_on_validation",
    "choose_weighting": "estimation.identification.weighting_choice",
    "compare": "estimation.identification.validation",
    "exported_mjcf": "estimation.identification.export",
    "exported_urdf": "estimation.identification.export",
    "fit_delay": "estimation.identification.delayed",
    "friction_document": "estimation.identification.export",
    "identify": "estimation.identification.fit",
    "implausible_estimates": "estimation.identification.fit",
    "implausible_links": "estimation.identification.export",
    "link_findings": "estimation.identification.plausibility",
    "link_reach": "estimation.identification.plausibility",
    "model_file_document": "estimation.identification.model_file",
    "plot_comparison": "estimation.identification.validation",
    "positive_base_parameters": "estimation.identification.plausibility",
    "preferred": "estimation.identification.preprocessing_choice",
    "prepare_records": "estimation.identification.prepared",
    "read_files": "estimation.identification.prepared",
    "read_model_file": "estimation.identification.model_file",
    "repeated_motion_note": "estimation.identification.repeated_motion",
    "shaped_blocks": "estimation.identification.shaped",
    "summed_model_file_document": "estimation.identification.model_file",
    "trivial_mse": "estimation.identification.trivial_predictors",
    "trivial_warnings": "estimation.identification.trivial_predictors",
    "weighting_samples": "estimation.identification.weighting_choice",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
