//! The VRML 97 parser: a file's statements into a [`Document`], an arena of nodes with their
//! locations (ISO/IEC 14772-1, clause 4 and annex A).
//!
//! Field values are read without a table of field types: the grammar lets a value's tokens say
//! what it is (numbers, strings, `TRUE`/`FALSE`, a node or `NULL`, or a bracketed list of one of
//! these), and the builder checks each value against the type its field has. `DEF` names a node and
//! `USE` refers to the same node again (the arena holds it once). A `PROTO` is expanded where it is
//! instantiated: its body's nodes are copied with the instance's field values (or the declared
//! defaults) in place of each `IS`, and the instance keeps the copies ([`Node::expansion`]). A
//! PROTO body has its own `DEF` names, as the standard says. `EXTERNPROTO` declarations and
//! `ROUTE`s are kept, not run.

use super::lex::{LexError, Lexer, Tok, Token};
use super::{Loc, MAX_PROTO_DEPTH, MAX_VRML_NESTING, MAX_VRML_NODES};
use std::collections::{HashMap, VecDeque};

/// A node of a [`Document`]'s arena.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(pub u32);

/// A field's value, as written.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// Numbers: every numeric type, single (`SFVec3f 1 2 3`) or multiple, bracketed or not.
    Numbers(Vec<f64>),
    Strings(Vec<String>),
    Bools(Vec<bool>),
    /// An `SFNode` (`NULL`: `None`).
    Node(Option<NodeId>),
    /// A bracketed list of nodes (`MFNode`).
    Nodes(Vec<NodeId>),
    /// `[]`: an empty list of any type.
    Empty,
    /// `IS name` in a PROTO body, before the body is copied for an instance.
    Is(String),
}

/// A field of a node, with the value written for it.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    pub name: String,
    pub loc: Loc,
    pub value: Value,
    /// In a copy of a PROTO body: the PROTO's interface field this one was `IS` (its value then is
    /// the instance's). Kept so that events sent to the instance can reach it.
    pub is: Option<String>,
}

/// A node: its type, `DEF` name, where it starts and its fields.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    pub type_name: String,
    pub def: Option<String>,
    pub loc: Loc,
    pub fields: Vec<Field>,
    /// For an instance of a PROTO declared in the file: its body's nodes, copied for it; the first
    /// is what the instance stands for in the scene.
    pub expansion: Option<Vec<NodeId>>,
    /// For an instance of an `EXTERNPROTO`: where that was declared.
    pub extern_proto: Option<Loc>,
}

impl Node {
    /// The field `name`, if written.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().rev().find(|f| f.name == name)
    }
}

/// What kind of interface declaration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldKind {
    Field,
    ExposedField,
    EventIn,
    EventOut,
}

/// A field or event a PROTO (or a Script) declares.
#[derive(Clone, Debug, PartialEq)]
pub struct Declaration {
    pub kind: FieldKind,
    pub type_name: String,
    pub name: String,
    /// The default value (fields and exposed fields of a PROTO).
    pub default: Value,
    pub loc: Loc,
}

/// A `PROTO` declaration.
#[derive(Clone, Debug, PartialEq)]
pub struct Proto {
    pub name: String,
    pub loc: Loc,
    pub interface: Vec<Declaration>,
    /// The body's nodes (templates, never placed in the scene themselves).
    pub body: Vec<NodeId>,
    /// How many PROTOs deep its expansion nests: 1, plus the deepest PROTO its body instantiates.
    pub depth: usize,
}

/// `ROUTE from.field TO to.field`.
#[derive(Clone, Debug, PartialEq)]
pub struct Route {
    pub from: (String, String),
    pub to: (String, String),
    pub loc: Loc,
    /// Written inside a PROTO body (its names are the body's).
    pub in_proto: bool,
}

/// A parsed file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Document {
    pub nodes: Vec<Node>,
    /// The top-level nodes, in file order.
    pub roots: Vec<NodeId>,
    /// The file's `DEF` names (outside PROTO bodies): the last node given each name.
    pub defs: HashMap<String, NodeId>,
    pub protos: Vec<Proto>,
    /// `EXTERNPROTO` names and where each was declared.
    pub extern_protos: Vec<(String, Loc)>,
    pub routes: Vec<Route>,
    /// Warnings found while parsing: where, what.
    pub warnings: Vec<(Loc, String)>,
}

impl Document {
    pub fn node(&self, id: NodeId) -> &Node {
        &self.nodes[id.0 as usize]
    }
}

/// A syntax error.
#[derive(Clone, Debug, PartialEq)]
pub struct ParseError {
    pub loc: Loc,
    pub message: String,
}

impl From<LexError> for ParseError {
    fn from(e: LexError) -> Self {
        ParseError { loc: e.loc, message: e.message }
    }
}

type Result<T> = std::result::Result<T, ParseError>;

/// The names one scope knows: the file, or a PROTO body.
#[derive(Default)]
struct Scope {
    defs: HashMap<String, NodeId>,
    protos: HashMap<String, ProtoRef>,
    /// The deepest PROTO instantiated in this scope so far.
    deepest: usize,
}

#[derive(Clone, Copy)]
enum ProtoRef {
    Local(usize),
    /// An EXTERNPROTO declared at this place.
    Extern(Loc),
}

/// Parses the text of a VRML 97 file (its header line included, which is a comment to the
/// grammar; the caller checks it).
pub fn parse(text: &str) -> Result<Document> {
    let mut p =
        Parser { lexer: Lexer::new(text), ahead: VecDeque::new(), doc: Document::default(), scopes: Vec::new() };
    p.scopes.push(Scope::default());
    while p.peek(0)?.is_some() {
        if let Some(node) = p.statement(0)? {
            p.doc.roots.push(node);
        }
    }
    let file_scope = p.scopes.pop().unwrap_or_default();
    p.doc.defs = file_scope.defs;
    Ok(p.doc)
}

struct Parser<'a> {
    lexer: Lexer<'a>,
    ahead: VecDeque<Token>,
    doc: Document,
    scopes: Vec<Scope>,
}

fn describe(tok: &Tok) -> String {
    match tok {
        Tok::Ident(s) => format!("`{s}`"),
        Tok::Number(..) => "a number".into(),
        Tok::Str(_) => "a string".into(),
        Tok::LBracket => "`[`".into(),
        Tok::RBracket => "`]`".into(),
        Tok::LBrace => "`{`".into(),
        Tok::RBrace => "`}`".into(),
        Tok::Period => "`.`".into(),
    }
}

const KEYWORDS: [&str; 14] = [
    "DEF",
    "USE",
    "PROTO",
    "EXTERNPROTO",
    "IS",
    "ROUTE",
    "TO",
    "NULL",
    "TRUE",
    "FALSE",
    "field",
    "exposedField",
    "eventIn",
    "eventOut",
];

impl Parser<'_> {
    fn peek(&mut self, k: usize) -> Result<Option<&Token>> {
        while self.ahead.len() <= k {
            match self.lexer.next_token()? {
                Some(t) => self.ahead.push_back(t),
                None => return Ok(None),
            }
        }
        Ok(self.ahead.get(k))
    }

    fn peek_tok(&mut self) -> Result<Option<Tok>> {
        Ok(self.peek(0)?.map(|t| t.tok.clone()))
    }

    fn next(&mut self, what: &str) -> Result<Token> {
        self.peek(0)?;
        match self.ahead.pop_front() {
            Some(t) => Ok(t),
            None => {
                Err(ParseError { loc: self.lexer.loc(), message: format!("the file ends where {what} was expected") })
            }
        }
    }

    /// The current scope (the file's or a PROTO body's); there is always one.
    fn scope(&mut self) -> &mut Scope {
        if self.scopes.is_empty() {
            self.scopes.push(Scope::default());
        }
        let last = self.scopes.len() - 1;
        &mut self.scopes[last]
    }

    fn expect(&mut self, tok: Tok, what: &str) -> Result<Loc> {
        let t = self.next(what)?;
        if t.tok != tok {
            return Err(ParseError { loc: t.loc, message: format!("expected {what}, found {}", describe(&t.tok)) });
        }
        Ok(t.loc)
    }

    fn ident(&mut self, what: &str) -> Result<(String, Loc)> {
        let t = self.next(what)?;
        match t.tok {
            Tok::Ident(s) if !KEYWORDS.contains(&s.as_str()) => Ok((s, t.loc)),
            other => Err(ParseError { loc: t.loc, message: format!("expected {what}, found {}", describe(&other)) }),
        }
    }

    fn push_node(&mut self, node: Node) -> Result<NodeId> {
        if self.doc.nodes.len() >= MAX_VRML_NODES {
            return Err(ParseError {
                loc: node.loc,
                message: format!("more than {MAX_VRML_NODES} nodes (PROTO instances counted as expanded)"),
            });
        }
        self.doc.nodes.push(node);
        Ok(NodeId(self.doc.nodes.len() as u32 - 1))
    }

    /// One statement: a node (returned), or a PROTO, EXTERNPROTO or ROUTE.
    fn statement(&mut self, depth: usize) -> Result<Option<NodeId>> {
        match self.peek_tok()? {
            Some(Tok::Ident(k)) if k == "PROTO" => self.proto(depth).map(|_| None),
            Some(Tok::Ident(k)) if k == "EXTERNPROTO" => self.extern_proto().map(|_| None),
            Some(Tok::Ident(k)) if k == "ROUTE" => self.route().map(|_| None),
            _ => self.node_statement(depth),
        }
    }

    /// `DEF name node`, `USE name` or a node; `None` for `NULL` and for a `USE` of an unknown name
    /// (a warning).
    fn node_statement(&mut self, depth: usize) -> Result<Option<NodeId>> {
        let t = self.next("a node")?;
        match t.tok {
            Tok::Ident(k) if k == "NULL" => Ok(None),
            Tok::Ident(k) if k == "DEF" => {
                let (name, _) = self.ident("a name after DEF")?;
                let id = self.node(depth, Some(name.clone()))?;
                self.scope().defs.insert(name, id);
                Ok(Some(id))
            }
            Tok::Ident(k) if k == "USE" => {
                let (name, loc) = self.ident("a name after USE")?;
                match self.scope().defs.get(&name) {
                    Some(&id) => Ok(Some(id)),
                    None => {
                        self.doc.warnings.push((loc, format!("USE {name}: no node is DEFined by that name here")));
                        Ok(None)
                    }
                }
            }
            tok => {
                self.ahead.push_front(Token { tok, loc: t.loc });
                self.node(depth, None).map(Some)
            }
        }
    }

    /// `Type { body }`.
    fn node(&mut self, depth: usize, def: Option<String>) -> Result<NodeId> {
        let (type_name, loc) = self.ident("a node type")?;
        if depth >= MAX_VRML_NESTING {
            return Err(ParseError { loc, message: format!("nodes nest deeper than {MAX_VRML_NESTING} levels") });
        }
        self.expect(Tok::LBrace, "`{` after the node type")?;
        let mut fields = Vec::new();
        loop {
            let t = self.next("a field name or `}`")?;
            let name = match t.tok {
                Tok::RBrace => break,
                Tok::Ident(k) if k == "PROTO" || k == "EXTERNPROTO" || k == "ROUTE" => {
                    self.ahead.push_front(Token { tok: Tok::Ident(k), loc: t.loc });
                    self.statement(depth + 1)?;
                    continue;
                }
                // A Script's own fields and events.
                Tok::Ident(k) if matches!(k.as_str(), "field" | "exposedField" | "eventIn" | "eventOut") => {
                    let d = self.declaration(&k, t.loc, depth, true)?;
                    if let Some(is) = self.is_clause()? {
                        fields.push(Field { name: d.name.clone(), loc: d.loc, value: Value::Is(is), is: None });
                    } else if matches!(d.kind, FieldKind::Field | FieldKind::ExposedField) {
                        fields.push(Field { name: d.name, loc: d.loc, value: d.default, is: None });
                    }
                    continue;
                }
                Tok::Ident(k) if !KEYWORDS.contains(&k.as_str()) => k,
                other => {
                    return Err(ParseError {
                        loc: t.loc,
                        message: format!("expected a field name or `}}`, found {}", describe(&other)),
                    })
                }
            };
            let value = match self.is_clause()? {
                Some(is) => Value::Is(is),
                None => self.value(depth)?,
            };
            fields.push(Field { name, loc: t.loc, value, is: None });
        }
        let proto = self.scopes.iter().rev().find_map(|s| s.protos.get(&type_name).copied());
        let mut node = Node { type_name, def, loc, fields, expansion: None, extern_proto: None };
        match proto {
            Some(ProtoRef::Local(index)) => {
                let expansion = self.instantiate(index, &node, depth)?;
                node.expansion = Some(expansion);
            }
            Some(ProtoRef::Extern(at)) => node.extern_proto = Some(at),
            None => {}
        }
        self.push_node(node)
    }

    /// `IS name`, if next.
    fn is_clause(&mut self) -> Result<Option<String>> {
        if matches!(self.peek(0)?, Some(Token { tok: Tok::Ident(k), .. }) if k == "IS") {
            self.next("IS")?;
            let (name, _) = self.ident("an interface field name after IS")?;
            return Ok(Some(name));
        }
        Ok(None)
    }

    /// A field value.
    fn value(&mut self, depth: usize) -> Result<Value> {
        let t = self.next("a field value")?;
        match t.tok {
            Tok::Number(x, _) => {
                let mut numbers = vec![x];
                while let Some(Token { tok: Tok::Number(x, _), .. }) = self.peek(0)? {
                    numbers.push(*x);
                    self.ahead.pop_front();
                }
                Ok(Value::Numbers(numbers))
            }
            Tok::Str(s) => Ok(Value::Strings(vec![s])),
            Tok::Ident(k) if k == "TRUE" => Ok(Value::Bools(vec![true])),
            Tok::Ident(k) if k == "FALSE" => Ok(Value::Bools(vec![false])),
            Tok::Ident(_) => {
                self.ahead.push_front(t);
                Ok(Value::Node(self.node_statement(depth + 1)?))
            }
            Tok::LBracket => self.list(t.loc, depth),
            other => {
                Err(ParseError { loc: t.loc, message: format!("expected a field value, found {}", describe(&other)) })
            }
        }
    }

    /// The rest of `[ ... ]`: values of one kind.
    fn list(&mut self, open: Loc, depth: usize) -> Result<Value> {
        let mut value = Value::Empty;
        loop {
            let Some(t) = self.peek(0)?.cloned() else {
                return Err(ParseError { loc: open, message: "`[` without its closing `]`".into() });
            };
            let mismatch = |loc: Loc| ParseError { loc, message: "a list mixes values of different types".to_string() };
            match (&t.tok, &mut value) {
                (Tok::RBracket, _) => {
                    self.ahead.pop_front();
                    return Ok(value);
                }
                (Tok::Number(x, _), Value::Empty) => value = Value::Numbers(vec![*x]),
                (Tok::Number(x, _), Value::Numbers(v)) => v.push(*x),
                (Tok::Str(s), Value::Empty) => value = Value::Strings(vec![s.clone()]),
                (Tok::Str(s), Value::Strings(v)) => v.push(s.clone()),
                (Tok::Ident(k), Value::Empty) if k == "TRUE" || k == "FALSE" => value = Value::Bools(vec![k == "TRUE"]),
                (Tok::Ident(k), Value::Bools(v)) if k == "TRUE" || k == "FALSE" => v.push(k == "TRUE"),
                (Tok::Ident(k), Value::Empty | Value::Nodes(_))
                    if !matches!(k.as_str(), "TRUE" | "FALSE" | "PROTO" | "EXTERNPROTO" | "ROUTE") =>
                {
                    let node = self.node_statement(depth + 1)?;
                    let mut nodes = match std::mem::replace(&mut value, Value::Empty) {
                        Value::Nodes(v) => v,
                        _ => Vec::new(),
                    };
                    nodes.extend(node);
                    value = Value::Nodes(nodes);
                    continue;
                }
                (Tok::Ident(k), _) if matches!(k.as_str(), "PROTO" | "EXTERNPROTO" | "ROUTE") => {
                    self.statement(depth + 1)?;
                    continue;
                }
                (Tok::Number(..) | Tok::Str(_) | Tok::Ident(_), _) => return Err(mismatch(t.loc)),
                (other, _) => {
                    return Err(ParseError {
                        loc: t.loc,
                        message: format!("expected a value or `]` in the list, found {}", describe(other)),
                    })
                }
            }
            self.ahead.pop_front();
        }
    }

    /// `kind type name [value]` of a PROTO's interface or a Script's body (`kind` read already).
    fn declaration(&mut self, kind: &str, loc: Loc, depth: usize, with_values: bool) -> Result<Declaration> {
        let kind = match kind {
            "field" => FieldKind::Field,
            "exposedField" => FieldKind::ExposedField,
            "eventIn" => FieldKind::EventIn,
            _ => FieldKind::EventOut,
        };
        let (type_name, _) = self.ident("a field type")?;
        let (name, _) = self.ident("a field name")?;
        let takes_value = with_values && matches!(kind, FieldKind::Field | FieldKind::ExposedField);
        // In a Script body a field may be `IS` instead of having a value.
        let is_next = matches!(self.peek(0)?, Some(Token { tok: Tok::Ident(k), .. }) if k == "IS");
        let default = if takes_value && !is_next { self.value(depth)? } else { Value::Empty };
        Ok(Declaration { kind, type_name, name, default, loc })
    }

    /// `PROTO name [ interface ] { body }`.
    fn proto(&mut self, depth: usize) -> Result<()> {
        let loc = self.expect(Tok::Ident("PROTO".into()), "PROTO")?;
        if depth >= MAX_VRML_NESTING {
            return Err(ParseError { loc, message: format!("nodes nest deeper than {MAX_VRML_NESTING} levels") });
        }
        let (name, _) = self.ident("the PROTO's name")?;
        self.expect(Tok::LBracket, "`[` and the PROTO's interface")?;
        let mut interface = Vec::new();
        loop {
            let t = self.next("an interface declaration or `]`")?;
            match t.tok {
                Tok::RBracket => break,
                Tok::Ident(k) if matches!(k.as_str(), "field" | "exposedField" | "eventIn" | "eventOut") => {
                    interface.push(self.declaration(&k, t.loc, depth, true)?);
                }
                other => {
                    return Err(ParseError {
                        loc: t.loc,
                        message: format!(
                        "expected field, exposedField, eventIn, eventOut or `]` in PROTO {name}'s interface, found {}",
                        describe(&other)
                    ),
                    })
                }
            }
        }
        self.expect(Tok::LBrace, "`{` and the PROTO's body")?;
        self.scopes.push(Scope::default());
        // The body's own PROTOs and DEFs stay in its scope; the PROTOs outside are visible.
        let mut body = Vec::new();
        let result = loop {
            match self.peek_tok()? {
                Some(Tok::RBrace) => {
                    self.next("`}`")?;
                    break Ok(());
                }
                None => break Err(ParseError { loc, message: format!("PROTO {name}'s body has no closing `}}`") }),
                _ => match self.statement(depth + 1) {
                    Ok(node) => body.extend(node),
                    Err(e) => break Err(e),
                },
            }
        };
        let scope = self.scopes.pop().unwrap_or_default();
        result?;
        if body.is_empty() {
            self.doc.warnings.push((loc, format!("PROTO {name} has no node in its body; its instances are empty")));
        }
        let depth_of = scope.deepest + 1;
        if depth_of > MAX_PROTO_DEPTH {
            return Err(ParseError {
                loc,
                message: format!("PROTO {name} instantiates PROTOs nested deeper than {MAX_PROTO_DEPTH} levels"),
            });
        }
        self.doc.protos.push(Proto { name: name.clone(), loc, interface, body, depth: depth_of });
        let index = self.doc.protos.len() - 1;
        self.scope().protos.insert(name, ProtoRef::Local(index));
        Ok(())
    }

    /// `EXTERNPROTO name [ interface ] urls`: recorded; its instances are skipped by the builder.
    fn extern_proto(&mut self) -> Result<()> {
        let loc = self.expect(Tok::Ident("EXTERNPROTO".into()), "EXTERNPROTO")?;
        let (name, _) = self.ident("the EXTERNPROTO's name")?;
        self.expect(Tok::LBracket, "`[` and the EXTERNPROTO's interface")?;
        loop {
            let t = self.next("an interface declaration or `]`")?;
            match t.tok {
                Tok::RBracket => break,
                Tok::Ident(k) if matches!(k.as_str(), "field" | "exposedField" | "eventIn" | "eventOut") => {
                    self.declaration(&k, t.loc, 0, false)?;
                }
                other => {
                    return Err(ParseError {
                        loc: t.loc,
                        message: format!("expected an interface declaration or `]`, found {}", describe(&other)),
                    })
                }
            }
        }
        // The URL list: a string or a bracketed list of strings.
        match self.value(0)? {
            Value::Strings(_) | Value::Empty => {}
            _ => return Err(ParseError { loc, message: format!("EXTERNPROTO {name}: expected its URL strings") }),
        }
        self.doc.extern_protos.push((name.clone(), loc));
        self.scope().protos.insert(name, ProtoRef::Extern(loc));
        Ok(())
    }

    /// `ROUTE a.b TO c.d`.
    fn route(&mut self) -> Result<()> {
        let loc = self.expect(Tok::Ident("ROUTE".into()), "ROUTE")?;
        let (from_node, _) = self.ident("the node a ROUTE leaves")?;
        self.expect(Tok::Period, "`.` and an event name")?;
        let (from_field, _) = self.ident("an event name")?;
        self.expect(Tok::Ident("TO".into()), "TO")?;
        let (to_node, _) = self.ident("the node a ROUTE reaches")?;
        self.expect(Tok::Period, "`.` and an event name")?;
        let (to_field, _) = self.ident("an event name")?;
        for name in [&from_node, &to_node] {
            if !self.scope().defs.contains_key(name) {
                self.doc.warnings.push((loc, format!("ROUTE names {name}, which no node is DEFined as before it")));
            }
        }
        let in_proto = self.scopes.len() > 1;
        self.doc.routes.push(Route { from: (from_node, from_field), to: (to_node, to_field), loc, in_proto });
        Ok(())
    }

    /// Copies PROTO `index`'s body for the instance `node` (its fields the values given), and
    /// returns the copies of its body's top-level nodes.
    fn instantiate(&mut self, index: usize, node: &Node, depth: usize) -> Result<Vec<NodeId>> {
        let proto = self.doc.protos[index].clone();
        {
            let scope = self.scope();
            scope.deepest = scope.deepest.max(proto.depth);
        }
        let mut values: HashMap<String, Value> = HashMap::new();
        for d in &proto.interface {
            values.insert(d.name.clone(), d.default.clone());
        }
        for f in &node.fields {
            match proto.interface.iter().find(|d| d.name == f.name) {
                Some(_) => {
                    values.insert(f.name.clone(), f.value.clone());
                }
                None => self
                    .doc
                    .warnings
                    .push((f.loc, format!("PROTO {} has no field {}; the value is ignored", proto.name, f.name))),
            }
        }
        let mut copies = HashMap::new();
        let mut roots = Vec::with_capacity(proto.body.len());
        for &b in &proto.body {
            roots.push(self.copy(b, &values, &mut copies, depth)?);
        }
        Ok(roots)
    }

    /// A copy of template node `id` (and of the nodes under it, each once) with `IS` fields
    /// replaced by `values`.
    fn copy(
        &mut self,
        id: NodeId,
        values: &HashMap<String, Value>,
        copies: &mut HashMap<NodeId, NodeId>,
        depth: usize,
    ) -> Result<NodeId> {
        if let Some(&done) = copies.get(&id) {
            return Ok(done);
        }
        let template = self.doc.node(id).clone();
        if depth >= MAX_VRML_NESTING {
            return Err(ParseError {
                loc: template.loc,
                message: format!("PROTO expansion nests nodes deeper than {MAX_VRML_NESTING} levels"),
            });
        }
        let mut fields = Vec::with_capacity(template.fields.len());
        for f in template.fields {
            let (value, is) = match f.value {
                Value::Is(name) => (values.get(&name).cloned().unwrap_or(Value::Empty), Some(name)),
                Value::Node(Some(n)) => (Value::Node(Some(self.copy(n, values, copies, depth + 1)?)), f.is),
                Value::Nodes(ns) => {
                    let mut out = Vec::with_capacity(ns.len());
                    for n in ns {
                        out.push(self.copy(n, values, copies, depth + 1)?);
                    }
                    (Value::Nodes(out), f.is)
                }
                v => (v, f.is),
            };
            fields.push(Field { name: f.name, loc: f.loc, value, is });
        }
        let expansion = match template.expansion {
            Some(nodes) => {
                let mut out = Vec::with_capacity(nodes.len());
                for n in nodes {
                    out.push(self.copy(n, values, copies, depth + 1)?);
                }
                Some(out)
            }
            None => None,
        };
        let copy = Node {
            type_name: template.type_name,
            def: template.def,
            loc: template.loc,
            fields,
            expansion,
            extern_proto: template.extern_proto,
        };
        let new = self.push_node(copy)?;
        copies.insert(id, new);
        Ok(new)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc(text: &str) -> Document {
        parse(text).unwrap_or_else(|e| panic!("{}:{}: {}", e.loc.line, e.loc.column, e.message))
    }

    fn field<'a>(d: &'a Document, id: NodeId, name: &str) -> &'a Value {
        &d.node(id).field(name).unwrap_or_else(|| panic!("no field {name}")).value
    }

    #[test]
    fn every_kind_of_value() {
        let d = doc(r#"#VRML V2.0 utf8
            Foo {
                f 1.5  v 1 2 3  i [ 1, 2, -1 ]  s "a b"  ms [ "x" "y" ]  b TRUE  mb [ FALSE TRUE ]
                n Bar { }  nn NULL  mn [ Bar {} Baz {} ]  e [ ]  img 2 1 1 0xFF 0x00
            }"#);
        assert_eq!(d.roots.len(), 1);
        let r = d.roots[0];
        assert_eq!(d.node(r).type_name, "Foo");
        assert_eq!(field(&d, r, "f"), &Value::Numbers(vec![1.5]));
        assert_eq!(field(&d, r, "v"), &Value::Numbers(vec![1.0, 2.0, 3.0]));
        assert_eq!(field(&d, r, "i"), &Value::Numbers(vec![1.0, 2.0, -1.0]));
        assert_eq!(field(&d, r, "s"), &Value::Strings(vec!["a b".into()]));
        assert_eq!(field(&d, r, "ms"), &Value::Strings(vec!["x".into(), "y".into()]));
        assert_eq!(field(&d, r, "b"), &Value::Bools(vec![true]));
        assert_eq!(field(&d, r, "mb"), &Value::Bools(vec![false, true]));
        assert!(matches!(field(&d, r, "n"), Value::Node(Some(n)) if d.node(*n).type_name == "Bar"));
        assert_eq!(field(&d, r, "nn"), &Value::Node(None));
        assert!(matches!(field(&d, r, "mn"), Value::Nodes(v) if v.len() == 2));
        assert_eq!(field(&d, r, "e"), &Value::Empty);
        assert_eq!(field(&d, r, "img"), &Value::Numbers(vec![2.0, 1.0, 1.0, 255.0, 0.0]));
        assert_eq!((d.node(r).loc.line, d.node(r).loc.column), (2, 13));
    }

    #[test]
    fn def_and_use_share_one_node() {
        let d = doc("DEF A Group { children [ DEF S Shape {} USE S ] } Transform { children USE A }");
        let Value::Nodes(kids) = field(&d, d.roots[0], "children") else { panic!() };
        assert_eq!(kids[0], kids[1]);
        assert_eq!(field(&d, d.roots[1], "children"), &Value::Node(Some(d.roots[0])));
        assert_eq!(d.defs.get("A"), Some(&d.roots[0]));
        assert_eq!(d.node(d.roots[0]).def.as_deref(), Some("A"));
        // An unknown name is a warning and no node.
        let d = doc("Group { children [ USE Nothing ] }");
        assert_eq!(field(&d, d.roots[0], "children"), &Value::Nodes(Vec::new()));
        assert!(d.warnings[0].1.contains("Nothing"), "{:?}", d.warnings);
    }

    #[test]
    fn protos_expand_with_is_and_defaults() {
        let d = doc(r#"
            PROTO Thing [ field SFVec3f where 1 2 3  exposedField SFFloat size 2  eventIn SFBool go ] {
                Transform { translation IS where  children [ DEF B Box { size IS size } USE B ] }
                Group {}
            }
            Thing { size 5 }
            DEF T2 Thing { where 0 0 0 }
            ROUTE T2.go TO T2.go
        "#);
        assert_eq!(d.roots.len(), 2);
        assert_eq!(d.protos[0].depth, 1);
        let first = d.node(d.roots[0]);
        assert_eq!(first.type_name, "Thing");
        let body = first.expansion.as_ref().expect("expanded");
        assert_eq!(body.len(), 2);
        let t = body[0];
        assert_eq!(d.node(t).type_name, "Transform");
        assert_eq!(field(&d, t, "translation"), &Value::Numbers(vec![1.0, 2.0, 3.0]));
        assert_eq!(d.node(t).field("translation").and_then(|f| f.is.as_deref()), Some("where"));
        let Value::Nodes(kids) = field(&d, t, "children") else { panic!() };
        // USE inside the body refers to the instance's own copy.
        assert_eq!(kids[0], kids[1]);
        assert_eq!(field(&d, kids[0], "size"), &Value::Numbers(vec![5.0]));
        // The second instance has its own copies.
        let second = d.node(d.roots[1]).expansion.as_ref().expect("expanded");
        assert_ne!(second[0], t);
        assert_eq!(field(&d, second[0], "translation"), &Value::Numbers(vec![0.0, 0.0, 0.0]));
        let Value::Nodes(kids2) = field(&d, second[0], "children") else { panic!() };
        assert_eq!(field(&d, kids2[0], "size"), &Value::Numbers(vec![2.0]));
        assert_eq!(d.routes.len(), 1);
        // The body's DEF names are its own.
        assert!(!d.defs.contains_key("B"));
    }

    #[test]
    fn protos_inside_protos_and_extern_protos() {
        let d = doc(r#"
            PROTO Inner [ field SFFloat r 1 ] { Sphere { radius IS r } }
            PROTO Outer [ field SFFloat r 3 ] { Shape { geometry Inner { r IS r } } }
            Outer { r 7 }
            EXTERNPROTO Far [ field SFFloat x ] [ "far.wrl#Far" "urn:x" ]
            Far { x 1 }
        "#);
        assert_eq!(d.protos[1].depth, 2);
        let shape = d.node(d.roots[0]).expansion.as_ref().expect("expanded")[0];
        let Value::Node(Some(inner)) = field(&d, shape, "geometry") else { panic!() };
        let sphere = d.node(*inner).expansion.as_ref().expect("expanded")[0];
        assert_eq!(field(&d, sphere, "radius"), &Value::Numbers(vec![7.0]));
        assert!(d.node(d.roots[1]).extern_proto.is_some());
        assert_eq!(d.extern_protos[0].0, "Far");
    }

    #[test]
    fn script_bodies_declare_their_own_fields() {
        let d =
            doc(r#"Script { eventIn SFTime touched field SFNode target USE X field SFInt32 n 3 url "javascript: 1" }"#);
        let s = d.roots[0];
        assert_eq!(field(&d, s, "n"), &Value::Numbers(vec![3.0]));
        assert!(d.warnings.iter().any(|(_, m)| m.contains("USE X")));
    }

    #[test]
    fn syntax_errors_name_line_and_column() {
        for (text, at, says) in [
            ("Group {\n  children [ Shape { ]\n}", (2, 22), "expected a field name"),
            ("Group { children [ 1 \"a\" ] }", (1, 22), "mixes"),
            ("Group {", (1, 8), "ends"),
            ("Transform { translation }", (1, 25), "expected a field value"),
            ("{ }", (1, 1), "expected a node type"),
            ("Group { children [ Shape {} }", (1, 29), "expected a value or `]`"),
            ("ROUTE a TO b.c", (1, 9), "`.`"),
            ("PROTO P [ field SFFloat x 1 ] { Box {} ", (1, 1), "no closing"),
            ("Shape { geometry Box { size 1 2 3 } } \"stray\"", (1, 39), "expected a node type"),
        ] {
            let e = parse(text).expect_err(text);
            assert_eq!((e.loc.line, e.loc.column), at, "{text}: {}", e.message);
            assert!(e.message.contains(says), "{text}: {}", e.message);
        }
    }

    #[test]
    fn nesting_is_bounded() {
        let deep = "Group { children [ ".repeat(MAX_VRML_NESTING + 1) + &" ] }".repeat(MAX_VRML_NESTING + 1);
        let e = parse(&deep).expect_err("too deep");
        assert!(e.message.contains("nest deeper"), "{}", e.message);
        let fits = "Group { children [ ".repeat(MAX_VRML_NESTING - 1) + &" ] }".repeat(MAX_VRML_NESTING - 1);
        assert!(parse(&fits).is_ok());
    }

    #[test]
    fn proto_expansion_is_bounded() {
        // Each PROTO doubles the one before: 2^40 nodes if nothing stopped it.
        let mut text = String::from("PROTO P0 [] { Group {} }\n");
        for k in 1..40 {
            text.push_str(&format!("PROTO P{k} [] {{ Group {{ children [ P{} {{}} P{} {{}} ] }} }}\n", k - 1, k - 1));
        }
        text.push_str("P39 {}\n");
        let e = parse(&text).expect_err("bounded");
        assert!(e.message.contains("nodes") || e.message.contains("deeper"), "{}", e.message);
    }
}
