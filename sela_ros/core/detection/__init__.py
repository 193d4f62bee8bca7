"""Has the robot changed? The damage detector's rule, and the evidence a restart of learning
needs."""
from sela_ros.core.detection.change_evidence import Evidence, EvidenceConfig
from sela_ros.core.detection.damage_detection import DamageDetector, DetectorConfig, Verdict

__all__ = ['DamageDetector', 'DetectorConfig', 'Evidence', 'EvidenceConfig', 'Verdict']
