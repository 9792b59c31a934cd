//! The standard VRML 97 node types (ISO/IEC 14772-1, clause 6) with the fields and events each
//! has, and what this reader does with each type.

/// What the builder does with a standard node type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Support {
    /// Read (possibly approximately: `docs/vrml.md`).
    Read,
    /// Left out with a warning: what it draws is missing from the image.
    Omitted,
    /// Left out with a warning: a Script or sound, which this reader does not run.
    Static,
    /// Left out silently: it has no effect on an image (WorldInfo).
    Silent,
    /// Run by animation (`super::events`: TimeSensor, the pointing-device, proximity and
    /// visibility sensors, the interpolators); nothing to draw.
    Runs,
}

/// Each standard node type: its fields, exposed fields and events (without the implicit
/// `set_`/`_changed` events of exposed fields, which [`knows_field`] accepts), and its support.
pub const NODE_TYPES: &[(&str, Support, &[&str])] = &[
    (
        "Anchor",
        Support::Read,
        &["children", "description", "parameter", "url", "bboxCenter", "bboxSize", "addChildren", "removeChildren"],
    ),
    ("Appearance", Support::Read, &["material", "texture", "textureTransform"]),
    (
        "AudioClip",
        Support::Static,
        &["description", "loop", "pitch", "startTime", "stopTime", "url", "duration_changed", "isActive"],
    ),
    (
        "Background",
        Support::Read,
        &[
            "groundAngle",
            "groundColor",
            "backUrl",
            "bottomUrl",
            "frontUrl",
            "leftUrl",
            "rightUrl",
            "topUrl",
            "skyAngle",
            "skyColor",
            "set_bind",
            "isBound",
        ],
    ),
    (
        "Billboard",
        Support::Read,
        &["axisOfRotation", "children", "bboxCenter", "bboxSize", "addChildren", "removeChildren"],
    ),
    ("Box", Support::Read, &["size"]),
    (
        "Collision",
        Support::Read,
        &["children", "collide", "bboxCenter", "bboxSize", "proxy", "collideTime", "addChildren", "removeChildren"],
    ),
    ("Color", Support::Read, &["color"]),
    ("ColorInterpolator", Support::Runs, &["key", "keyValue", "set_fraction", "value_changed"]),
    ("Cone", Support::Read, &["bottomRadius", "height", "side", "bottom"]),
    ("Coordinate", Support::Read, &["point"]),
    ("CoordinateInterpolator", Support::Runs, &["key", "keyValue", "set_fraction", "value_changed"]),
    ("Cylinder", Support::Read, &["bottom", "height", "radius", "side", "top"]),
    (
        "CylinderSensor",
        Support::Runs,
        &[
            "autoOffset",
            "diskAngle",
            "enabled",
            "maxAngle",
            "minAngle",
            "offset",
            "isActive",
            "rotation_changed",
            "trackPoint_changed",
        ],
    ),
    ("DirectionalLight", Support::Read, &["ambientIntensity", "color", "direction", "intensity", "on"]),
    (
        "ElevationGrid",
        Support::Read,
        &[
            "color",
            "normal",
            "texCoord",
            "height",
            "ccw",
            "colorPerVertex",
            "creaseAngle",
            "normalPerVertex",
            "solid",
            "xDimension",
            "xSpacing",
            "zDimension",
            "zSpacing",
            "set_height",
        ],
    ),
    (
        "Extrusion",
        Support::Read,
        &[
            "beginCap",
            "ccw",
            "convex",
            "creaseAngle",
            "crossSection",
            "endCap",
            "orientation",
            "scale",
            "solid",
            "spine",
            "set_crossSection",
            "set_orientation",
            "set_scale",
            "set_spine",
        ],
    ),
    ("Fog", Support::Read, &["color", "fogType", "visibilityRange", "set_bind", "isBound"]),
    (
        "FontStyle",
        Support::Silent,
        &["family", "horizontal", "justify", "language", "leftToRight", "size", "spacing", "style", "topToBottom"],
    ),
    ("Group", Support::Read, &["children", "bboxCenter", "bboxSize", "addChildren", "removeChildren"]),
    ("ImageTexture", Support::Read, &["url", "repeatS", "repeatT"]),
    (
        "IndexedFaceSet",
        Support::Read,
        &[
            "color",
            "coord",
            "normal",
            "texCoord",
            "ccw",
            "colorIndex",
            "colorPerVertex",
            "convex",
            "coordIndex",
            "creaseAngle",
            "normalIndex",
            "normalPerVertex",
            "solid",
            "texCoordIndex",
            "set_colorIndex",
            "set_coordIndex",
            "set_normalIndex",
            "set_texCoordIndex",
        ],
    ),
    (
        "IndexedLineSet",
        Support::Omitted,
        &["color", "coord", "colorIndex", "colorPerVertex", "coordIndex", "set_colorIndex", "set_coordIndex"],
    ),
    ("Inline", Support::Read, &["url", "bboxCenter", "bboxSize"]),
    ("LOD", Support::Read, &["level", "center", "range"]),
    (
        "Material",
        Support::Read,
        &["ambientIntensity", "diffuseColor", "emissiveColor", "shininess", "specularColor", "transparency"],
    ),
    (
        "MovieTexture",
        Support::Omitted,
        &["loop", "speed", "startTime", "stopTime", "url", "repeatS", "repeatT", "duration_changed", "isActive"],
    ),
    (
        "NavigationInfo",
        Support::Read,
        &["avatarSize", "headlight", "speed", "type", "visibilityLimit", "set_bind", "isBound"],
    ),
    ("Normal", Support::Read, &["vector"]),
    ("NormalInterpolator", Support::Runs, &["key", "keyValue", "set_fraction", "value_changed"]),
    ("OrientationInterpolator", Support::Runs, &["key", "keyValue", "set_fraction", "value_changed"]),
    ("PixelTexture", Support::Read, &["image", "repeatS", "repeatT"]),
    (
        "PlaneSensor",
        Support::Runs,
        &[
            "autoOffset",
            "enabled",
            "maxPosition",
            "minPosition",
            "offset",
            "isActive",
            "trackPoint_changed",
            "translation_changed",
        ],
    ),
    (
        "PointLight",
        Support::Read,
        &["ambientIntensity", "attenuation", "color", "intensity", "location", "on", "radius"],
    ),
    ("PointSet", Support::Omitted, &["color", "coord"]),
    ("PositionInterpolator", Support::Runs, &["key", "keyValue", "set_fraction", "value_changed"]),
    (
        "ProximitySensor",
        Support::Runs,
        &["center", "size", "enabled", "isActive", "position_changed", "orientation_changed", "enterTime", "exitTime"],
    ),
    ("ScalarInterpolator", Support::Runs, &["key", "keyValue", "set_fraction", "value_changed"]),
    ("Script", Support::Static, &["url", "directOutput", "mustEvaluate"]),
    ("Shape", Support::Read, &["appearance", "geometry"]),
    (
        "Sound",
        Support::Static,
        &[
            "direction",
            "intensity",
            "location",
            "maxBack",
            "maxFront",
            "minBack",
            "minFront",
            "priority",
            "source",
            "spatialize",
        ],
    ),
    ("Sphere", Support::Read, &["radius"]),
    (
        "SphereSensor",
        Support::Runs,
        &["autoOffset", "enabled", "offset", "isActive", "rotation_changed", "trackPoint_changed"],
    ),
    (
        "SpotLight",
        Support::Read,
        &[
            "ambientIntensity",
            "attenuation",
            "beamWidth",
            "color",
            "cutOffAngle",
            "direction",
            "intensity",
            "location",
            "on",
            "radius",
        ],
    ),
    ("Switch", Support::Read, &["choice", "whichChoice"]),
    ("Text", Support::Omitted, &["string", "fontStyle", "length", "maxExtent"]),
    ("TextureCoordinate", Support::Read, &["point"]),
    ("TextureTransform", Support::Read, &["center", "rotation", "scale", "translation"]),
    (
        "TimeSensor",
        Support::Runs,
        &[
            "cycleInterval",
            "enabled",
            "loop",
            "startTime",
            "stopTime",
            "cycleTime",
            "fraction_changed",
            "isActive",
            "time",
        ],
    ),
    (
        "TouchSensor",
        Support::Runs,
        &["enabled", "hitNormal_changed", "hitPoint_changed", "hitTexCoord_changed", "isActive", "isOver", "touchTime"],
    ),
    (
        "Transform",
        Support::Read,
        &[
            "center",
            "children",
            "rotation",
            "scale",
            "scaleOrientation",
            "translation",
            "bboxCenter",
            "bboxSize",
            "addChildren",
            "removeChildren",
        ],
    ),
    (
        "Viewpoint",
        Support::Read,
        &["fieldOfView", "jump", "orientation", "position", "description", "set_bind", "bindTime", "isBound"],
    ),
    ("VisibilitySensor", Support::Runs, &["center", "enabled", "size", "enterTime", "exitTime", "isActive"]),
    ("WorldInfo", Support::Silent, &["info", "title"]),
];

/// The entry of standard node type `name`.
pub fn node_type(name: &str) -> Option<(Support, &'static [&'static str])> {
    NODE_TYPES.iter().find(|(n, _, _)| *n == name).map(|&(_, s, f)| (s, f))
}

/// Whether `field` is a field or event of a node with these `fields` (an exposed field `x` also
/// has the events `set_x` and `x_changed`).
pub fn knows_field(fields: &[&str], field: &str) -> bool {
    let base = field.strip_prefix("set_").or_else(|| field.strip_suffix("_changed"));
    fields.contains(&field) || base.is_some_and(|b| fields.contains(&b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_has_every_standard_node_once() {
        assert_eq!(NODE_TYPES.len(), 54);
        for (k, (name, _, _)) in NODE_TYPES.iter().enumerate() {
            assert!(NODE_TYPES[k + 1..].iter().all(|(n, _, _)| n != name), "{name} twice");
        }
        let (support, fields) = node_type("Transform").expect("known");
        assert_eq!(support, Support::Read);
        assert!(knows_field(fields, "set_translation") && knows_field(fields, "rotation_changed"));
        assert!(!knows_field(fields, "translate"));
        assert!(node_type("Separator").is_none());
    }
}
