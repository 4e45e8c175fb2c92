"""help() of the module says what each public function, class and attribute is: every one has a
docstring of its own (nanobind gives an undocumented attribute only its signature, "(self) ->
...", and a function only its signature line)."""

import inspect

import mjsysid


def public():
    for name in sorted(dir(mjsysid)):
        obj = getattr(mjsysid, name)
        if not name.startswith("_") and (inspect.isclass(obj) or callable(obj)):
            yield name, obj


def test_every_public_function_and_class_has_a_docstring():
    names = []
    for name, obj in public():
        doc = (obj.__doc__ or "").strip()
        # a function's doc starts with its signature line; the text after it is the docstring
        text = doc.split("\n\n", 1)[1] if doc.startswith(name + "(") and "\n\n" in doc else doc
        assert text and not text.startswith(name + "("), name
        names.append(name)
    assert {"fit", "fit_experiment", "FitResult", "ResultFile", "SequenceResult"} <= set(names)


def test_every_attribute_and_method_has_a_docstring():
    bare = []
    for name, cls in public():
        if not inspect.isclass(cls):
            continue
        for attr, value in vars(cls).items():
            if attr.startswith("_"):
                continue
            doc = (getattr(value, "__doc__", None) or "").strip()
            # a method's doc is "NAME(self...) -> T" then its text
            if isinstance(value, property):
                text = "" if doc.startswith("(self)") else doc
            else:
                text = doc.split("\n\n", 1)[1] if "\n\n" in doc else ""
            if not text:
                bare.append(f"{name}.{attr}")
    assert bare == []


def test_help_shows_the_tables():
    text = inspect.getdoc(mjsysid.FitResult.to_dict)
    assert "result.yaml" in text
    assert "pandas" in inspect.getdoc(mjsysid.FitResult.to_pandas)
    assert "'auto'" in inspect.getdoc(mjsysid.fit) and "starts" in inspect.getdoc(mjsysid.fit)
