//! The shader types: a term the syntax tree, the IR, the interface and the runtime share.

/// The shader types of the language and our extensions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ShaderKind {
    Surface,
    Light,
    Displacement,
    Volume,
    /// RenderMan's imager; `pixel` is a synonym.
    Imager,
    /// Generates primary rays (OpenRT extension).
    Camera,
    /// Looks up a light field on a surface (OpenRT extension).
    Lightfield,
}

impl ShaderKind {
    pub fn name(self) -> &'static str {
        match self {
            ShaderKind::Surface => "surface",
            ShaderKind::Light => "light",
            ShaderKind::Displacement => "displacement",
            ShaderKind::Volume => "volume",
            ShaderKind::Imager => "imager",
            ShaderKind::Camera => "camera",
            ShaderKind::Lightfield => "lightfield",
        }
    }

    /// The name with its indefinite article, for messages ("an imager", "a surface").
    pub fn with_article(self) -> String {
        let article = if self.name().starts_with(['a', 'e', 'i', 'o', 'u']) { "an" } else { "a" };
        format!("{article} {}", self.name())
    }

    pub const ALL: [ShaderKind; 7] = [
        ShaderKind::Surface,
        ShaderKind::Light,
        ShaderKind::Displacement,
        ShaderKind::Volume,
        ShaderKind::Imager,
        ShaderKind::Camera,
        ShaderKind::Lightfield,
    ];
}
